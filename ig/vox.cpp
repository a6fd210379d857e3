// MagicaVoxel .vox reader and writer (the public "MagicaVoxel-file-format-vox.txt"): a RIFF-like
// file of chunks, each "id, content bytes, children bytes, content, children", little-endian.
#include "ig/vox.hpp"

#include "base/check.hpp"
#include "base/text.hpp"
#include "ig/error.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string_view>

namespace ig {
namespace {

constexpr std::uint32_t kVersion = 150;
// The largest file read: 256^3 voxels of 4 bytes and room for scene chunks.
constexpr std::size_t kMaxFileBytes = std::size_t{512} << 20;
// Grid cells of all a file's models together: one full 256^3 model.
constexpr std::uint64_t kMaxTotalCells = std::uint64_t{1} << 24;

std::uint32_t le32(const std::uint8_t* p) {
    return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
           (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24);
}

void put32(std::vector<std::uint8_t>& out, std::uint32_t v) {
    for (int i = 0; i < 4; ++i)
        out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

void putId(std::vector<std::uint8_t>& out, const char* id) {
    for (int i = 0; i < 4; ++i)
        out.push_back(static_cast<std::uint8_t>(id[i]));
}

std::string chunkName(const std::uint8_t* id) {
    return base::quoted(std::string_view(reinterpret_cast<const char*>(id), 4));
}

class Parser {
  public:
    Parser(std::span<const std::uint8_t> bytes, const std::string& name) : b_(bytes), name_(name) {}

    [[noreturn]] void fail(const std::string& where, std::size_t offset,
                           const std::string& what) const {
        throw InputError(name_ + ": " + where + " at byte " + std::to_string(offset) + ": " + what);
    }

    VoxFile parse() {
        if (b_.empty()) throw InputError(name_ + ": empty file (expected a MagicaVoxel .vox)");
        if (b_.size() < 8 || std::memcmp(b_.data(), "VOX ", 4) != 0) {
            throw InputError(name_ + ": not a MagicaVoxel file (it does not start with 'VOX ')");
        }
        const std::uint32_t version = le32(b_.data() + 4);
        if (version < 150 || version > 255) {
            throw InputError(name_ + ": .vox version " + std::to_string(version) +
                             " (expected 150..255)");
        }
        if (b_.size() < 20) fail("MAIN chunk", 8, "truncated (the file ends inside its header)");
        if (std::memcmp(b_.data() + 8, "MAIN", 4) != 0) {
            fail("first chunk " + chunkName(b_.data() + 8), 8, "expected MAIN");
        }
        const std::uint64_t content = le32(b_.data() + 12), children = le32(b_.data() + 16);
        const std::uint64_t end = 20 + content + children;
        if (end > b_.size()) {
            fail("MAIN chunk", 8,
                 "its sizes (" + std::to_string(content) + " + " + std::to_string(children) +
                     " bytes) run past the end of the file (" + std::to_string(b_.size()) +
                     " bytes)");
        }
        VoxFile file;
        file.palette = defaultVoxPalette();
        std::size_t pos = 20 + content;
        while (pos < end)
            pos = chunk(pos, end, file);
        if (pendingSize_) fail("SIZE chunk", sizeOffset_, "not followed by an XYZI chunk");
        if (file.models.empty()) throw InputError(name_ + ": no model (no SIZE/XYZI chunks)");
        if (packCount_ >= 0 && static_cast<std::size_t>(packCount_) != file.models.size()) {
            fail("PACK chunk", packOffset_,
                 "says " + std::to_string(packCount_) + " models, the file has " +
                     std::to_string(file.models.size()));
        }
        return file;
    }

  private:
    // Reads the chunk at `pos` (inside a parent ending at `end`); returns the offset after it.
    std::size_t chunk(std::size_t pos, std::size_t end, VoxFile& file) {
        if (end - pos < 12)
            fail("chunk", pos, "truncated header (" + std::to_string(end - pos) + " bytes left)");
        const std::uint8_t* id = b_.data() + pos;
        const std::uint64_t content = le32(id + 4), children = le32(id + 8);
        const std::string name = chunkName(id) + " chunk";
        if (12 + content + children > end - pos) {
            fail(name, pos,
                 "its sizes (" + std::to_string(content) + " + " + std::to_string(children) +
                     " bytes) run past the end of its parent (" + std::to_string(end - pos - 12) +
                     " bytes left)");
        }
        const std::uint8_t* c = id + 12;
        auto need = [&](std::uint64_t n) {
            if (content < n) {
                fail(name, pos,
                     "content of " + std::to_string(content) + " bytes, expected " +
                         std::to_string(n));
            }
        };
        if (std::memcmp(id, "PACK", 4) == 0) {
            need(4);
            packCount_ = le32(c);
            packOffset_ = pos;
            if (packCount_ == 0) fail(name, pos, "0 models");
        } else if (std::memcmp(id, "SIZE", 4) == 0) {
            need(12);
            if (pendingSize_) fail(name, pos, "follows a SIZE chunk with no XYZI between");
            for (int k = 0; k < 3; ++k) {
                const std::uint32_t s = le32(c + 4 * k);
                if (s == 0 || s > static_cast<std::uint32_t>(kVoxMaxSide)) {
                    fail(name, pos,
                         std::string("side ") + "xyz"[k] + " = " + std::to_string(s) +
                             " (expected 1..256)");
                }
                size_[k] = static_cast<int>(s);
            }
            pendingSize_ = true;
            sizeOffset_ = pos;
        } else if (std::memcmp(id, "XYZI", 4) == 0) {
            need(4);
            if (!pendingSize_) fail(name, pos, "no SIZE chunk before it");
            pendingSize_ = false;
            const std::uint64_t n = le32(c);
            if (4 + 4 * n > content) {
                fail(name, pos,
                     std::to_string(n) + " voxels need " + std::to_string(4 + 4 * n) +
                         " bytes, the chunk has " + std::to_string(content));
            }
            const std::uint64_t cells = static_cast<std::uint64_t>(size_[0]) * size_[1] * size_[2];
            totalCells_ += cells;
            if (totalCells_ > kMaxTotalCells) {
                fail(name, pos,
                     "the models hold more than " + std::to_string(kMaxTotalCells) +
                         " grid cells together (256^3 at most)");
            }
            VoxModel m(size_[0], size_[1], size_[2]);
            for (std::uint64_t i = 0; i < n; ++i) {
                const std::uint8_t* v = c + 4 + 4 * i;
                if (v[0] >= m.sizeX || v[1] >= m.sizeY || v[2] >= m.sizeZ) {
                    fail(name, pos,
                         "voxel " + std::to_string(i) + " at (" + std::to_string(v[0]) + ", " +
                             std::to_string(v[1]) + ", " + std::to_string(v[2]) +
                             ") lies outside the model's SIZE " + std::to_string(m.sizeX) + " x " +
                             std::to_string(m.sizeY) + " x " + std::to_string(m.sizeZ));
                }
                if (v[3] == 0) {
                    fail(name, pos,
                         "voxel " + std::to_string(i) + " has colour index 0 (1..255 expected)");
                }
                m.set(v[0], v[1], v[2], v[3]);
            }
            file.models.push_back(std::move(m));
        } else if (std::memcmp(id, "RGBA", 4) == 0) {
            need(1024);
            // Colour i of the chunk is palette index i + 1; the chunk's last entry is unused.
            file.palette[0] = Rgba8{0, 0, 0, 0};
            for (int i = 0; i < 255; ++i) {
                const std::uint8_t* p = c + 4 * i;
                file.palette[i + 1] = Rgba8{p[0], p[1], p[2], p[3]};
            }
            file.hasPalette = true;
        }
        // Children of any chunk other than MAIN are skipped with it (unknown chunks included).
        return pos + 12 + content + children;
    }

    std::span<const std::uint8_t> b_;
    const std::string& name_;
    int size_[3] = {0, 0, 0};
    bool pendingSize_ = false;
    std::size_t sizeOffset_ = 0;
    long long packCount_ = -1;
    std::uint64_t totalCells_ = 0;
    std::size_t packOffset_ = 0;
};

}  // namespace

std::size_t VoxModel::filled() const {
    std::size_t n = 0;
    for (const std::uint8_t v : voxels)
        n += v != 0;
    return n;
}

const std::array<Rgba8, 256>& defaultVoxPalette() {
    // Index 1..215: the 6 x 6 x 6 colour cube (levels ff, cc, 99, 66, 33, 00), red slowest and
    // blue fastest, without black; 216..255: ramps of red, green, blue and grey (ee dd bb aa 88
    // 77 55 44 22 11). Entry 0 is unused.
    static const std::array<Rgba8, 256> palette = [] {
        std::array<Rgba8, 256> p{};
        p[0] = Rgba8{0, 0, 0, 0};
        int i = 1;
        for (int r = 0; r < 6; ++r)
            for (int g = 0; g < 6; ++g)
                for (int b = 0; b < 6; ++b) {
                    if (r == 5 && g == 5 && b == 5) continue;
                    auto level = [](int k) { return static_cast<std::uint8_t>(0xff - 0x33 * k); };
                    p[i++] = Rgba8{level(r), level(g), level(b), 255};
                }
        const std::uint8_t ramp[10] = {0xee, 0xdd, 0xbb, 0xaa, 0x88, 0x77, 0x55, 0x44, 0x22, 0x11};
        for (int channel = 0; channel < 4; ++channel) {
            for (const std::uint8_t v : ramp) {
                Rgba8 c{0, 0, 0, 255};
                if (channel == 0 || channel == 3) c.r = v;
                if (channel == 1 || channel == 3) c.g = v;
                if (channel == 2 || channel == 3) c.b = v;
                p[i++] = c;
            }
        }
        CHECK_EQ(i, 256);
        return p;
    }();
    return palette;
}

VoxFile parseVox(std::span<const std::uint8_t> bytes, const std::string& name) {
    return Parser(bytes, name).parse();
}

VoxFile readVox(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path + ": cannot open (" + std::strerror(errno) + ")");
    std::vector<std::uint8_t> bytes;
    char buf[1 << 16];
    while (in.read(buf, sizeof buf) || in.gcount() > 0) {
        bytes.insert(bytes.end(), buf, buf + in.gcount());
        if (bytes.size() > kMaxFileBytes) {
            throw InputError(path + ": larger than " + std::to_string(kMaxFileBytes >> 20) +
                             " MiB, too large for a .vox model");
        }
    }
    if (in.bad()) throw InputError(path + ": read error");
    return parseVox(bytes, path);
}

std::vector<std::uint8_t> encodeVox(const VoxFile& file) {
    std::vector<std::uint8_t> body;
    if (file.models.size() > 1) {
        putId(body, "PACK");
        put32(body, 4);
        put32(body, 0);
        put32(body, static_cast<std::uint32_t>(file.models.size()));
    }
    for (const VoxModel& m : file.models) {
        CHECK(m.sizeX >= 1 && m.sizeX <= kVoxMaxSide && m.sizeY >= 1 && m.sizeY <= kVoxMaxSide &&
              m.sizeZ >= 1 && m.sizeZ <= kVoxMaxSide)
            << "model " << m.sizeX << " x " << m.sizeY << " x " << m.sizeZ;
        CHECK_EQ(m.voxels.size(), static_cast<std::size_t>(m.sizeX) * m.sizeY * m.sizeZ);
        putId(body, "SIZE");
        put32(body, 12);
        put32(body, 0);
        put32(body, static_cast<std::uint32_t>(m.sizeX));
        put32(body, static_cast<std::uint32_t>(m.sizeY));
        put32(body, static_cast<std::uint32_t>(m.sizeZ));
        const std::size_t n = m.filled();
        putId(body, "XYZI");
        put32(body, static_cast<std::uint32_t>(4 + 4 * n));
        put32(body, 0);
        put32(body, static_cast<std::uint32_t>(n));
        for (int z = 0; z < m.sizeZ; ++z)
            for (int y = 0; y < m.sizeY; ++y)
                for (int x = 0; x < m.sizeX; ++x) {
                    const std::uint8_t v = m.at(x, y, z);
                    if (v == 0) continue;
                    body.push_back(static_cast<std::uint8_t>(x));
                    body.push_back(static_cast<std::uint8_t>(y));
                    body.push_back(static_cast<std::uint8_t>(z));
                    body.push_back(v);
                }
    }
    putId(body, "RGBA");
    put32(body, 1024);
    put32(body, 0);
    for (int i = 1; i <= 256; ++i) {
        const Rgba8 c = i < 256 ? file.palette[i] : Rgba8{0, 0, 0, 0};
        for (const std::uint8_t v : {c.r, c.g, c.b, c.a})
            body.push_back(v);
    }
    std::vector<std::uint8_t> out;
    putId(out, "VOX ");
    put32(out, kVersion);
    putId(out, "MAIN");
    put32(out, 0);
    put32(out, static_cast<std::uint32_t>(body.size()));
    out.reserve(out.size() + body.size());
    for (const std::uint8_t v : body)
        out.push_back(v);
    return out;
}

void writeVox(const std::string& path, const VoxFile& file) {
    const std::vector<std::uint8_t> bytes = encodeVox(file);
    const std::string tmp = path + ".tmp";
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) throw InputError(path + ": cannot write (" + std::strerror(errno) + ")");
        out.write(reinterpret_cast<const char*>(bytes.data()),
                  static_cast<std::streamsize>(bytes.size()));
        out.close();
        if (!out) {
            std::remove(tmp.c_str());
            throw InputError(path + ": write failed");
        }
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const int e = errno;
        std::remove(tmp.c_str());
        throw InputError(path + ": cannot rename into place (" + std::strerror(e) + ")");
    }
}

}  // namespace ig
