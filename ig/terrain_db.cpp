// The database file: a fixed header, the tiles, the index (one entry per tile with its offset,
// size and CRC-32) and the CRS text. Little-endian throughout. The header is written last, so
// a file whose writing stopped part-way has no valid header; the writer also writes to a
// temporary name and renames only after fsync.
#include "ig/terrain_db.hpp"

#include "base/check.hpp"
#include "base/text.hpp"
#include "ig/error.hpp"
#include "ig/slope_bound.hpp"
#include "ig/terrain_io.hpp"

#include <fcntl.h>
#include <lz4.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

namespace ig {

static_assert(std::endian::native == std::endian::little, "the database is little-endian");
static_assert(sizeof(Rgb8) == 3);

namespace {

constexpr char kMagic[8] = {'V', 'I', 'G', 'T', 'E', 'R', 'D', 'B'};
constexpr std::uint32_t kTileMagic = 0x4C495456;  // "VTIL"
constexpr std::size_t kHeaderBytes = 256, kEntryBytes = 24, kTileHeaderBytes = 24;
constexpr int kZstdLevel = 1;

template <class T>
void put(std::uint8_t* p, T v) {
    std::memcpy(p, &v, sizeof v);
}
template <class T>
T get(const std::uint8_t* p) {
    T v;
    std::memcpy(&v, p, sizeof v);
    return v;
}

std::uint32_t crc32Of(const std::uint8_t* p, std::size_t n) {
    uLong c = crc32(0L, Z_NULL, 0);
    while (n > 0) {
        const uInt chunk = static_cast<uInt>(std::min<std::size_t>(n, 1u << 30));
        c = crc32(c, p, chunk);
        p += chunk;
        n -= chunk;
    }
    return static_cast<std::uint32_t>(c);
}

// The slope section lies right after the header.
constexpr std::uint64_t kSlopeOffset = kHeaderBytes;
std::uint64_t slopeSectionBytes(int width, int height) {
    return static_cast<std::uint64_t>(SlopeBlocks::blocksAlong(width)) *
           static_cast<std::uint64_t>(SlopeBlocks::blocksAlong(height)) * sizeof(float);
}

int ceilHalf(int n) {
    return (n + 1) / 2;
}
int ceilDiv(int a, int b) {
    return (a + b - 1) / b;
}

std::size_t payloadBytes(TileKind kind, int w, int h) {
    const std::size_t n = static_cast<std::size_t>(w) * h;
    if (kind == TileKind::Nodes) return n * 2;
    return n * 2 + n * 3 + static_cast<std::size_t>(w - 1) * (h - 1) * 2;
}

// Embedded databases start on this boundary (a multiple of every page size in use), so that
// their header and slope section map on their own.
constexpr std::uint64_t kEmbedAlign = 65536;
// An inset's entry: seven i32 (x0, y0, x1, y1, factor, mapX0, mapY0), u32 zero, u64 offset,
// u64 bytes, the name (NUL-padded).
constexpr std::size_t kInsetNameBytes = 128, kInsetEntryBytes = 48 + kInsetNameBytes;
constexpr std::uint32_t kMaxInsets = 4096;

std::string sysError() {
    return std::strerror(errno);
}

void writeAll(int fd, const std::uint8_t* p, std::size_t n, std::uint64_t offset,
              const std::string& path) {
    while (n > 0) {
        const ssize_t w = ::pwrite(fd, p, n, static_cast<off_t>(offset));
        if (w < 0) {
            if (errno == EINTR) continue;
            throw InputError(path + ": cannot write: " + sysError());
        }
        p += w;
        n -= static_cast<std::size_t>(w);
        offset += static_cast<std::uint64_t>(w);
    }
}

// Reads exactly n bytes; false when the file ends first.
bool readAll(int fd, std::uint8_t* p, std::size_t n, std::uint64_t offset,
             const std::string& path) {
    while (n > 0) {
        const ssize_t r = ::pread(fd, p, n, static_cast<off_t>(offset));
        if (r < 0) {
            if (errno == EINTR) continue;
            throw InputError(path + ": cannot read: " + sysError());
        }
        if (r == 0) return false;
        p += r;
        n -= static_cast<std::size_t>(r);
        offset += static_cast<std::uint64_t>(r);
    }
    return true;
}

}  // namespace

const char* tileCodecName(TileCodec codec) {
    switch (codec) {
        case TileCodec::None:
            return "none";
        case TileCodec::Lz4:
            return "lz4";
        case TileCodec::Zstd:
            return "zstd";
    }
    return "?";
}

TileCodec parseTileCodec(const std::string& name) {
    if (name == "none") return TileCodec::None;
    if (name == "lz4") return TileCodec::Lz4;
    if (name == "zstd") return TileCodec::Zstd;
    throw InputError("--codec: '" + name + "' is not one of none, lz4, zstd");
}

std::string describeTile(const TileKey& key) {
    return std::string(key.kind == TileKind::Display ? "display" : "node") + " tile (level " +
           std::to_string(key.level) + ", " + std::to_string(key.tx) + ", " +
           std::to_string(key.ty) + ")";
}

// --- layout ---------------------------------------------------------------------------------

TerrainDbLayout::TerrainDbLayout(int width, int height, int tileSize) : tileSize_(tileSize) {
    CHECK(width >= 2 && height >= 2);
    CHECK(tileSize >= kMinDbTileSize && tileSize <= kMaxDbTileSize &&
          std::has_single_bit(static_cast<unsigned>(tileSize)));
    // Display levels as TerrainPyramid builds them (no level limit).
    levelW_.push_back(width);
    levelH_.push_back(height);
    for (;;) {
        const int cw = ceilHalf(levelW_.back() - 1), ch = ceilHalf(levelH_.back() - 1);
        if (cw < 2 || ch < 2) break;
        levelW_.push_back(cw + 1);
        levelH_.push_back(ch + 1);
    }
    // Node levels likewise (entry 0 stands for the level-0 cells).
    nodeW_.push_back(width - 1);
    nodeH_.push_back(height - 1);
    while (nodeW_.back() > 1 || nodeH_.back() > 1 || nodeW_.size() < 2) {
        nodeW_.push_back(ceilHalf(nodeW_.back()));
        nodeH_.push_back(ceilHalf(nodeH_.back()));
    }
    for (int k = 0; k < displayLevels(); ++k) {
        displayBase_.push_back(entryCount_);
        entryCount_ +=
            static_cast<std::int64_t>(tilesX(TileKind::Display, k)) * tilesY(TileKind::Display, k);
    }
    nodeBase_.assign(1, -1);
    for (int j = 1; j < nodeLevels(); ++j) {
        nodeBase_.push_back(entryCount_);
        entryCount_ +=
            static_cast<std::int64_t>(tilesX(TileKind::Nodes, j)) * tilesY(TileKind::Nodes, j);
    }
}

int TerrainDbLayout::tilesX(TileKind kind, int level) const {
    return kind == TileKind::Display ? ceilDiv(levelW_[level] - 1, tileSize_)
                                     : ceilDiv(nodeW_[level], tileSize_);
}

int TerrainDbLayout::tilesY(TileKind kind, int level) const {
    return kind == TileKind::Display ? ceilDiv(levelH_[level] - 1, tileSize_)
                                     : ceilDiv(nodeH_[level], tileSize_);
}

std::int64_t TerrainDbLayout::entryIndex(const TileKey& key) const {
    if (key.kind == TileKind::Display) {
        if (key.level < 0 || key.level >= displayLevels()) return -1;
    } else if (key.kind == TileKind::Nodes) {
        if (key.level < 1 || key.level >= nodeLevels()) return -1;
    } else {
        return -1;
    }
    const int nx = tilesX(key.kind, key.level), ny = tilesY(key.kind, key.level);
    if (key.tx < 0 || key.ty < 0 || key.tx >= nx || key.ty >= ny) return -1;
    const std::int64_t base =
        key.kind == TileKind::Display ? displayBase_[key.level] : nodeBase_[key.level];
    return base + static_cast<std::int64_t>(key.ty) * nx + key.tx;
}

TileKey TerrainDbLayout::keyAt(std::int64_t index) const {
    CHECK(index >= 0 && index < entryCount_);
    TileKey key;
    int level = 0;
    if (index < (nodeBase_.size() > 1 ? nodeBase_[1] : entryCount_)) {
        key.kind = TileKind::Display;
        while (level + 1 < displayLevels() && displayBase_[level + 1] <= index)
            ++level;
        index -= displayBase_[level];
    } else {
        key.kind = TileKind::Nodes;
        level = 1;
        while (level + 1 < nodeLevels() && nodeBase_[level + 1] <= index)
            ++level;
        index -= nodeBase_[level];
    }
    key.level = level;
    const int nx = tilesX(key.kind, level);
    key.tx = static_cast<int>(index % nx);
    key.ty = static_cast<int>(index / nx);
    return key;
}

void TerrainDbLayout::tileExtent(const TileKey& key, int& x0, int& y0, int& width,
                                 int& height) const {
    const int t = tileSize_;
    x0 = key.tx * t;
    y0 = key.ty * t;
    if (key.kind == TileKind::Display) {
        width = std::min(t, levelW_[key.level] - 1 - x0) + 1;
        height = std::min(t, levelH_[key.level] - 1 - y0) + 1;
    } else {
        width = std::min(t, nodeW_[key.level] - x0);
        height = std::min(t, nodeH_[key.level] - y0);
    }
}

// --- encoding -------------------------------------------------------------------------------

std::vector<std::uint8_t> encodeTile(const TerrainTile& tile, TileCodec codec,
                                     std::uint32_t& rawPayloadBytes) {
    const std::size_t raw = payloadBytes(tile.key.kind, tile.width, tile.height);
    const std::size_t n = static_cast<std::size_t>(tile.width) * tile.height;
    if (tile.key.kind == TileKind::Display) {
        CHECK(tile.heights.size() == n && tile.colors.size() == n &&
              tile.maxima.size() == static_cast<std::size_t>(tile.width - 1) * (tile.height - 1));
    } else {
        CHECK(tile.maxima.size() == n);
    }
    std::vector<std::uint8_t> payload(raw);
    std::uint8_t* p = payload.data();
    if (tile.key.kind == TileKind::Display) {
        std::memcpy(p, tile.heights.data(), n * 2);
        p += n * 2;
        std::memcpy(p, tile.colors.data(), n * 3);
        p += n * 3;
    }
    std::memcpy(p, tile.maxima.data(), tile.maxima.size() * 2);
    rawPayloadBytes = static_cast<std::uint32_t>(raw);

    std::uint8_t hdr[kTileHeaderBytes] = {};
    put<std::uint32_t>(hdr, kTileMagic);
    hdr[4] = static_cast<std::uint8_t>(tile.key.kind);
    hdr[5] = static_cast<std::uint8_t>(tile.key.level);
    hdr[6] = static_cast<std::uint8_t>(codec);
    put<std::uint32_t>(hdr + 8, static_cast<std::uint32_t>(tile.key.tx));
    put<std::uint32_t>(hdr + 12, static_cast<std::uint32_t>(tile.key.ty));
    put<std::uint32_t>(hdr + 16, static_cast<std::uint32_t>(tile.width));
    put<std::uint32_t>(hdr + 20, static_cast<std::uint32_t>(tile.height));
    std::vector<std::uint8_t> out;
    switch (codec) {
        case TileCodec::None:
            out.resize(kTileHeaderBytes + raw);
            std::memcpy(out.data() + kTileHeaderBytes, payload.data(), raw);
            break;
        case TileCodec::Lz4: {
            const int bound = LZ4_compressBound(static_cast<int>(raw));
            out.resize(kTileHeaderBytes + static_cast<std::size_t>(bound));
            const int m =
                LZ4_compress_default(reinterpret_cast<const char*>(payload.data()),
                                     reinterpret_cast<char*>(out.data()) + kTileHeaderBytes,
                                     static_cast<int>(raw), bound);
            CHECK(m > 0);
            out.resize(kTileHeaderBytes + static_cast<std::size_t>(m));
            break;
        }
        case TileCodec::Zstd: {
            const std::size_t bound = ZSTD_compressBound(raw);
            out.resize(kTileHeaderBytes + bound);
            const std::size_t m = ZSTD_compress(out.data() + kTileHeaderBytes, bound,
                                                payload.data(), raw, kZstdLevel);
            CHECK(!ZSTD_isError(m));
            out.resize(kTileHeaderBytes + m);
            break;
        }
    }
    std::memcpy(out.data(), hdr, kTileHeaderBytes);
    return out;
}

// --- writer ---------------------------------------------------------------------------------

namespace {

// Copies the whole of `from` into `fd` at `at`; returns its size.
std::uint64_t copyFileInto(const std::string& from, int fd, std::uint64_t at,
                           const std::string& to) {
    const int in = ::open(from.c_str(), O_RDONLY | O_CLOEXEC);
    if (in < 0) throw InputError(from + ": cannot open: " + sysError());
    std::vector<std::uint8_t> buf(std::size_t{1} << 20);
    std::uint64_t done = 0;
    for (;;) {
        const ssize_t r = ::pread(in, buf.data(), buf.size(), static_cast<off_t>(done));
        if (r < 0 && errno == EINTR) continue;
        if (r < 0) {
            const std::string why = sysError();
            ::close(in);
            throw InputError(from + ": cannot read: " + why);
        }
        if (r == 0) break;
        writeAll(fd, buf.data(), static_cast<std::size_t>(r), at + done, to);
        done += static_cast<std::uint64_t>(r);
    }
    ::close(in);
    return done;
}

}  // namespace

TerrainDbWriter::TerrainDbWriter(const std::string& path, const TerrainDbLayout& layout,
                                 TileCodec codec)
    : path_(path), tmpPath_(path + ".partial"), layout_(layout), codec_(codec) {
    fd_ = ::open(tmpPath_.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) throw InputError(tmpPath_ + ": cannot create: " + sysError());
    // The header stays zero (no magic) until finish().
    const std::vector<std::uint8_t> zero(kHeaderBytes, 0);
    writeAll(fd_, zero.data(), zero.size(), 0, tmpPath_);
    // The slope section's place is reserved; its rows come as the level-0 rows do.
    const int width = layout_.levelWidth(0), height = layout_.levelHeight(0);
    end_ = kSlopeOffset + slopeSectionBytes(width, height);
    index_.assign(static_cast<std::size_t>(layout_.entryCount()) * kEntryBytes, 0);
    written_.assign(static_cast<std::size_t>(layout_.entryCount()), 0);
}

TerrainDbWriter::~TerrainDbWriter() {
    if (fd_ >= 0) ::close(fd_);
    if (!finished_) ::unlink(tmpPath_.c_str());
}

void TerrainDbWriter::append(const TileKey& key, const std::vector<std::uint8_t>& stored,
                             std::uint32_t rawPayloadBytes) {
    const std::int64_t i = layout_.entryIndex(key);
    CHECK(i >= 0 && !written_[static_cast<std::size_t>(i)]);
    writeAll(fd_, stored.data(), stored.size(), end_, tmpPath_);
    std::uint8_t* e = index_.data() + static_cast<std::size_t>(i) * kEntryBytes;
    put<std::uint64_t>(e, end_);
    put<std::uint32_t>(e + 8, static_cast<std::uint32_t>(stored.size()));
    put<std::uint32_t>(e + 12, rawPayloadBytes);
    put<std::uint32_t>(e + 16, crc32Of(stored.data(), stored.size()));
    put<std::uint32_t>(e + 20, 0);
    end_ += stored.size();
    written_[static_cast<std::size_t>(i)] = 1;
}

void TerrainDbWriter::writeSlopeRow(int by, const float* bounds) {
    const int bx = SlopeBlocks::blocksAlong(layout_.levelWidth(0));
    const int rows = SlopeBlocks::blocksAlong(layout_.levelHeight(0));
    CHECK(by == slopeRowsWritten_ && by < rows);
    const std::size_t bytes = static_cast<std::size_t>(bx) * sizeof(float);
    writeAll(fd_, reinterpret_cast<const std::uint8_t*>(bounds), bytes,
             kSlopeOffset + static_cast<std::uint64_t>(by) * bytes, tmpPath_);
    ++slopeRowsWritten_;
}

void TerrainDbWriter::write(const TerrainTile& tile) {
    std::uint32_t raw = 0;
    const std::vector<std::uint8_t> stored = encodeTile(tile, codec_, raw);
    append(tile.key, stored, raw);
}

std::uint64_t TerrainDbWriter::finish(const TerrainDbInfo& info,
                                      const std::vector<Embedded>& insets) {
    CHECK(!finished_);
    CHECK(std::all_of(written_.begin(), written_.end(), [](std::uint8_t w) { return w != 0; }));
    CHECK(slopeRowsWritten_ == SlopeBlocks::blocksAlong(layout_.levelHeight(0)));
    // The slope section's checksum, read back (its rows were written as they came).
    const std::uint64_t slopeBytes =
        slopeSectionBytes(layout_.levelWidth(0), layout_.levelHeight(0));
    uLong slopeCrc = crc32(0L, Z_NULL, 0);
    {
        std::vector<std::uint8_t> chunk(std::size_t{1} << 20);
        for (std::uint64_t at = 0; at < slopeBytes; at += chunk.size()) {
            const std::size_t n =
                static_cast<std::size_t>(std::min<std::uint64_t>(chunk.size(), slopeBytes - at));
            CHECK(readAll(fd_, chunk.data(), n, kSlopeOffset + at, tmpPath_));
            slopeCrc = crc32(slopeCrc, chunk.data(), static_cast<uInt>(n));
        }
    }
    const std::uint64_t indexOffset = end_;
    writeAll(fd_, index_.data(), index_.size(), indexOffset, tmpPath_);
    const std::uint64_t crsOffset = indexOffset + index_.size();
    writeAll(fd_, reinterpret_cast<const std::uint8_t*>(info.crs.data()), info.crs.size(),
             crsOffset, tmpPath_);
    // The embedded insets, each a whole database on a boundary of kEmbedAlign (the reader
    // maps each one's header and slope section), then their table.
    std::uint64_t end = crsOffset + info.crs.size();
    std::vector<std::uint8_t> table(insets.size() * kInsetEntryBytes, 0);
    for (std::size_t k = 0; k < insets.size(); ++k) {
        const DbInset& in = insets[k].inset;
        end = (end + kEmbedAlign - 1) / kEmbedAlign * kEmbedAlign;
        const std::uint64_t bytes = copyFileInto(insets[k].file, fd_, end, tmpPath_);
        std::uint8_t* e = table.data() + k * kInsetEntryBytes;
        const int fields[7] = {in.x0, in.y0, in.x1, in.y1, in.factor, in.mapX0, in.mapY0};
        for (int f = 0; f < 7; ++f)
            put<std::int32_t>(e + 4 * f, fields[f]);
        put<std::uint64_t>(e + 32, end);
        put<std::uint64_t>(e + 40, bytes);
        const std::size_t n = std::min<std::size_t>(in.name.size(), kInsetNameBytes - 1);
        std::memcpy(e + 48, in.name.data(), n);
        end += bytes;
    }
    const std::uint64_t tableOffset = end;
    writeAll(fd_, table.data(), table.size(), tableOffset, tmpPath_);
    std::uint8_t h[kHeaderBytes] = {};
    std::memcpy(h, kMagic, 8);
    put<std::uint32_t>(h + 8, kTerrainDbVersion);
    put<std::uint32_t>(h + 12, static_cast<std::uint32_t>(layout_.tileSize()));
    put<std::uint32_t>(h + 16, static_cast<std::uint32_t>(info.width));
    put<std::uint32_t>(h + 20, static_cast<std::uint32_t>(info.height));
    put<std::uint32_t>(h + 24, static_cast<std::uint32_t>(layout_.displayLevels()));
    put<std::uint32_t>(h + 28, static_cast<std::uint32_t>(layout_.nodeLevels()));
    put<double>(h + 32, info.spacingX);
    put<double>(h + 40, info.spacingY);
    put<double>(h + 48, info.heightScale);
    put<double>(h + 56, info.heightOffset);
    put<double>(h + 64, info.originX);
    put<double>(h + 72, info.originY);
    put<std::uint16_t>(h + 80, info.minRaw);
    put<std::uint16_t>(h + 82, info.maxRaw);
    h[84] = static_cast<std::uint8_t>(codec_);
    put<std::uint64_t>(h + 88, indexOffset);
    put<std::uint64_t>(h + 96, static_cast<std::uint64_t>(layout_.entryCount()));
    put<std::uint32_t>(h + 104, crc32Of(index_.data(), index_.size()));
    put<std::uint32_t>(h + 108, static_cast<std::uint32_t>(info.crs.size()));
    put<std::uint64_t>(h + 112, crsOffset);
    put<std::uint64_t>(h + 120, kSlopeOffset);
    put<std::uint32_t>(h + 128, static_cast<std::uint32_t>(slopeCrc));
    put<std::uint16_t>(h + 132, info.maxDx);
    put<std::uint16_t>(h + 134, info.maxDy);
    put<std::uint64_t>(h + 136, tableOffset);
    put<std::uint32_t>(h + 144, static_cast<std::uint32_t>(insets.size()));
    put<std::uint32_t>(h + 148, crc32Of(table.data(), table.size()));
    put<std::uint32_t>(h + 252, crc32Of(h, 252));
    writeAll(fd_, h, kHeaderBytes, 0, tmpPath_);
    if (::fsync(fd_) != 0) throw InputError(tmpPath_ + ": cannot sync: " + sysError());
    ::close(fd_);
    fd_ = -1;
    if (!keepTemporary_ && ::rename(tmpPath_.c_str(), path_.c_str()) != 0) {
        throw InputError(path_ + ": cannot rename " + tmpPath_ + " into place: " + sysError());
    }
    finished_ = true;
    for (const Embedded& e : insets)
        ::unlink(e.file.c_str());
    return tableOffset + table.size();
}

// --- reader ---------------------------------------------------------------------------------

TerrainDb::TerrainDb(TerrainDb&& o) noexcept
    : path_(std::move(o.path_)),
      file_(std::move(o.file_)),
      base_(o.base_),
      insets_(std::move(o.insets_)),
      fd_(o.fd_),
      info_(std::move(o.info_)),
      layout_(std::move(o.layout_)),
      codec_(o.codec_),
      fileBytes_(o.fileBytes_),
      indexOffset_(o.indexOffset_),
      index_(std::move(o.index_)),
      mapped_(o.mapped_),
      mappedBytes_(o.mappedBytes_),
      slopes_(o.slopes_) {
    o.fd_ = -1;
    o.mapped_ = nullptr;
    o.mappedBytes_ = 0;
    o.slopes_ = nullptr;
}

TerrainDb& TerrainDb::operator=(TerrainDb&& o) noexcept {
    if (this != &o) {
        if (fd_ >= 0) ::close(fd_);
        path_ = std::move(o.path_);
        file_ = std::move(o.file_);
        base_ = o.base_;
        insets_ = std::move(o.insets_);
        fd_ = o.fd_;
        o.fd_ = -1;
        info_ = std::move(o.info_);
        layout_ = std::move(o.layout_);
        codec_ = o.codec_;
        fileBytes_ = o.fileBytes_;
        indexOffset_ = o.indexOffset_;
        index_ = std::move(o.index_);
        if (mapped_) ::munmap(mapped_, mappedBytes_);
        mapped_ = std::exchange(o.mapped_, nullptr);
        mappedBytes_ = std::exchange(o.mappedBytes_, 0);
        slopes_ = std::exchange(o.slopes_, nullptr);
    }
    return *this;
}

TerrainDb::~TerrainDb() {
    if (fd_ >= 0) ::close(fd_);
    if (mapped_) ::munmap(mapped_, mappedBytes_);
}

double TerrainDbInfo::maxSlope() const {
    // As TerrainMap::updateRange computes it.
    const double gx = maxDx * std::abs(heightScale) / spacingX;
    const double gy = maxDy * std::abs(heightScale) / spacingY;
    return std::sqrt(gx * gx + gy * gy);
}

TerrainDb TerrainDb::open(const std::string& path) {
    return openAt(path, path, 0, 0);
}

TerrainDb TerrainDb::openInset(std::size_t k) const {
    CHECK(k < insets_.size());
    const DbInset& in = insets_[k];
    return openAt(file_, path_ + " (inset " + base::quoted(in.name) + ")", base_ + in.offset,
                  in.bytes);
}

TerrainDb TerrainDb::openAt(const std::string& file, const std::string& path, std::uint64_t base,
                            std::uint64_t bytes) {
    TerrainDb db;
    db.path_ = path;
    db.file_ = file;
    db.base_ = base;
    db.fd_ = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
    if (db.fd_ < 0) throw InputError(path + ": cannot open: " + sysError());
    struct stat st {};
    if (::fstat(db.fd_, &st) != 0) throw InputError(path + ": cannot stat: " + sysError());
    auto fail = [&](const std::string& what) { throw InputError(path + ": " + what); };
    const std::uint64_t fileSize = static_cast<std::uint64_t>(st.st_size);
    if (base > fileSize || (bytes > 0 && bytes > fileSize - base)) {
        fail("truncated (the file ends inside the embedded database)");
    }
    db.fileBytes_ = bytes > 0 ? bytes : fileSize - base;

    std::uint8_t h[kHeaderBytes];
    if (!readAll(db.fd_, h, kHeaderBytes, base, path)) {
        fail("not a terrain database (shorter than its header)");
    }
    if (std::memcmp(h, kMagic, 8) != 0) {
        fail("not a terrain database (no VIGTERDB header; an unfinished build leaves none)");
    }
    const std::uint32_t version = get<std::uint32_t>(h + 8);
    if (version != kTerrainDbVersion && version != 2) {
        fail("database format version " + std::to_string(version) + "; this program reads " +
             std::to_string(kTerrainDbVersion) + " (rebuild it with ig-build-db)");
    }
    if (crc32Of(h, 252) != get<std::uint32_t>(h + 252)) fail("header checksum mismatch (corrupt)");
    const std::uint32_t tile = get<std::uint32_t>(h + 12);
    const std::uint32_t w = get<std::uint32_t>(h + 16), hh = get<std::uint32_t>(h + 20);
    if (tile < kMinDbTileSize || tile > kMaxDbTileSize || !std::has_single_bit(tile)) {
        fail("header: tile size " + std::to_string(tile) + " is not a power of two from " +
             std::to_string(kMinDbTileSize) + " to " + std::to_string(kMaxDbTileSize));
    }
    if (w < 2 || hh < 2 || w > (1u << 24) || hh > (1u << 24)) {
        fail("header: map size " + std::to_string(w) + " x " + std::to_string(hh) +
             " out of range");
    }
    TerrainDbInfo& info = db.info_;
    info.width = static_cast<int>(w);
    info.height = static_cast<int>(hh);
    info.spacingX = get<double>(h + 32);
    info.spacingY = get<double>(h + 40);
    info.heightScale = get<double>(h + 48);
    info.heightOffset = get<double>(h + 56);
    info.originX = get<double>(h + 64);
    info.originY = get<double>(h + 72);
    info.minRaw = get<std::uint16_t>(h + 80);
    info.maxRaw = get<std::uint16_t>(h + 82);
    for (double v : {info.spacingX, info.spacingY, info.heightScale}) {
        if (!(std::isfinite(v) && v > 0)) fail("header: spacing or height scale not positive");
    }
    if (!std::isfinite(info.heightOffset)) fail("header: height offset not finite");
    if (h[84] > 2) fail("header: unknown tile codec " + std::to_string(h[84]));
    db.codec_ = static_cast<TileCodec>(h[84]);
    db.layout_ = TerrainDbLayout(info.width, info.height, static_cast<int>(tile));
    if (get<std::uint32_t>(h + 24) != static_cast<std::uint32_t>(db.layout_.displayLevels()) ||
        get<std::uint32_t>(h + 28) != static_cast<std::uint32_t>(db.layout_.nodeLevels())) {
        fail("header: level counts disagree with the map size");
    }
    const std::uint64_t indexOffset = get<std::uint64_t>(h + 88);
    const std::uint64_t entries = get<std::uint64_t>(h + 96);
    if (entries != static_cast<std::uint64_t>(db.layout_.entryCount())) {
        fail("index: " + std::to_string(entries) + " entries, the map's layout has " +
             std::to_string(db.layout_.entryCount()));
    }
    const std::uint64_t indexBytes = entries * kEntryBytes;
    const std::uint32_t crsBytes = get<std::uint32_t>(h + 108);
    const std::uint64_t crsOffset = get<std::uint64_t>(h + 112);
    if (indexOffset < kHeaderBytes || crsOffset != indexOffset + indexBytes ||
        crsOffset + crsBytes > db.fileBytes_) {
        fail("truncated (" + std::to_string(db.fileBytes_) + " bytes; the header places the " +
             "index and CRS up to byte " + std::to_string(crsOffset + crsBytes) + ")");
    }
    info.maxDx = get<std::uint16_t>(h + 132);
    info.maxDy = get<std::uint16_t>(h + 134);
    const std::uint64_t slopeBytes = slopeSectionBytes(info.width, info.height);
    if (get<std::uint64_t>(h + 120) != kSlopeOffset) fail("header: slope section out of place");
    if (kSlopeOffset + slopeBytes > indexOffset) {
        fail("header: the slope section (" + std::to_string(slopeBytes) +
             " bytes) overlaps the index");
    }
    {
        uLong crc = crc32(0L, Z_NULL, 0);
        std::vector<std::uint8_t> chunk(std::size_t{1} << 20);
        for (std::uint64_t at = 0; at < slopeBytes; at += chunk.size()) {
            const std::size_t n =
                static_cast<std::size_t>(std::min<std::uint64_t>(chunk.size(), slopeBytes - at));
            if (!readAll(db.fd_, chunk.data(), n, base + kSlopeOffset + at, path)) {
                fail("truncated slope section");
            }
            crc = crc32(crc, chunk.data(), static_cast<uInt>(n));
        }
        if (static_cast<std::uint32_t>(crc) != get<std::uint32_t>(h + 128)) {
            fail("slope section checksum mismatch (corrupt slope bounds)");
        }
    }
    db.mappedBytes_ = static_cast<std::size_t>(kSlopeOffset + slopeBytes);
    void* m =
        ::mmap(nullptr, db.mappedBytes_, PROT_READ, MAP_SHARED, db.fd_, static_cast<off_t>(base));
    if (m == MAP_FAILED) fail("cannot map the slope section: " + sysError());
    db.mapped_ = m;
    db.slopes_ = reinterpret_cast<const float*>(static_cast<const std::uint8_t*>(m) + kSlopeOffset);
    db.indexOffset_ = indexOffset;
    db.index_.resize(indexBytes);
    if (!readAll(db.fd_, db.index_.data(), indexBytes, base + indexOffset, path)) {
        fail("truncated index");
    }
    if (crc32Of(db.index_.data(), indexBytes) != get<std::uint32_t>(h + 104)) {
        fail("index checksum mismatch (corrupt index)");
    }
    info.crs.resize(crsBytes);
    if (crsBytes > 0 && !readAll(db.fd_, reinterpret_cast<std::uint8_t*>(info.crs.data()), crsBytes,
                                 base + crsOffset, path)) {
        fail("truncated CRS");
    }
    // Every entry inside the tile area, with the size its tile must have.
    for (std::int64_t i = 0; i < db.layout_.entryCount(); ++i) {
        const std::uint8_t* e = db.index_.data() + static_cast<std::size_t>(i) * kEntryBytes;
        const TileKey key = db.layout_.keyAt(i);
        int x0, y0, tw, th;
        db.layout_.tileExtent(key, x0, y0, tw, th);
        const std::uint64_t off = get<std::uint64_t>(e);
        const std::uint32_t stored = get<std::uint32_t>(e + 8);
        if (off < kSlopeOffset + slopeBytes || stored < kTileHeaderBytes ||
            off + stored > indexOffset ||
            get<std::uint32_t>(e + 12) != payloadBytes(key.kind, tw, th)) {
            fail("index entry of " + describeTile(key) +
                 " disagrees with the layout (offset, size or payload size out of place)");
        }
    }
    if (version >= 3) {
        // The insets: their table after the last embedded database, each database after the
        // CRS and before the table, on the embedding boundary, none overlapping.
        const std::uint64_t tableOffset = get<std::uint64_t>(h + 136);
        const std::uint32_t count = get<std::uint32_t>(h + 144);
        if (count > 0 && bytes > 0) fail("an inset's database holds insets of its own");
        if (count > kMaxInsets) fail("header: " + std::to_string(count) + " insets");
        const std::uint64_t tableBytes = std::uint64_t{count} * kInsetEntryBytes;
        if (tableOffset < crsOffset + crsBytes || tableOffset + tableBytes > db.fileBytes_) {
            fail("truncated (the insets table ends past the file's " +
                 std::to_string(db.fileBytes_) + " bytes)");
        }
        std::vector<std::uint8_t> table(tableBytes);
        if (!readAll(db.fd_, table.data(), tableBytes, base + tableOffset, path)) {
            fail("truncated insets table");
        }
        if (crc32Of(table.data(), tableBytes) != get<std::uint32_t>(h + 148)) {
            fail("insets table checksum mismatch (corrupt)");
        }
        std::uint64_t after = crsOffset + crsBytes;
        for (std::uint32_t k = 0; k < count; ++k) {
            const std::uint8_t* e = table.data() + std::size_t{k} * kInsetEntryBytes;
            DbInset in;
            in.x0 = get<std::int32_t>(e);
            in.y0 = get<std::int32_t>(e + 4);
            in.x1 = get<std::int32_t>(e + 8);
            in.y1 = get<std::int32_t>(e + 12);
            in.factor = get<std::int32_t>(e + 16);
            in.mapX0 = get<std::int32_t>(e + 20);
            in.mapY0 = get<std::int32_t>(e + 24);
            in.offset = get<std::uint64_t>(e + 32);
            in.bytes = get<std::uint64_t>(e + 40);
            const char* name = reinterpret_cast<const char*>(e + 48);
            in.name.assign(name, strnlen(name, kInsetNameBytes));
            if (in.name.empty()) in.name = "inset " + std::to_string(k + 1);
            if (in.offset % kEmbedAlign != 0 || in.offset < after || in.bytes < kHeaderBytes ||
                in.offset + in.bytes > tableOffset) {
                fail("insets table: " + in.name + "'s database lies out of place");
            }
            if (in.x0 < 0 || in.y0 < 0 || in.x1 <= in.x0 || in.y1 <= in.y0 || in.x1 >= info.width ||
                in.y1 >= info.height || in.factor < 2 || in.factor > 256 ||
                !std::has_single_bit(static_cast<unsigned>(in.factor))) {
                fail("insets table: " + in.name + "'s placement lies outside the map");
            }
            after = in.offset + in.bytes;
            db.insets_.push_back(std::move(in));
        }
    }
    return db;
}

std::uint32_t TerrainDb::storedBytes(const TileKey& key) const {
    const std::int64_t i = layout_.entryIndex(key);
    CHECK(i >= 0);
    return get<std::uint32_t>(index_.data() + static_cast<std::size_t>(i) * kEntryBytes + 8);
}

TerrainTile TerrainDb::readTile(const TileKey& key) const {
    const std::int64_t i = layout_.entryIndex(key);
    if (i < 0) throw InputError(path_ + ": " + describeTile(key) + " is not in the database");
    const std::uint8_t* e = index_.data() + static_cast<std::size_t>(i) * kEntryBytes;
    const std::uint64_t off = get<std::uint64_t>(e);
    const std::uint32_t stored = get<std::uint32_t>(e + 8), raw = get<std::uint32_t>(e + 12);
    auto fail = [&](const std::string& what) {
        throw InputError(path_ + ": " + describeTile(key) + ": " + what);
    };
    std::vector<std::uint8_t> buf(stored);
    if (!readAll(fd_, buf.data(), stored, base_ + off, path_)) {
        fail("truncated (the file ends inside it)");
    }
    if (crc32Of(buf.data(), stored) != get<std::uint32_t>(e + 16)) {
        fail("checksum mismatch (corrupt tile)");
    }
    TerrainTile tile;
    tile.key = key;
    layout_.tileExtent(key, tile.x0, tile.y0, tile.width, tile.height);
    const std::uint8_t* th = buf.data();
    if (get<std::uint32_t>(th) != kTileMagic || th[4] != static_cast<std::uint8_t>(key.kind) ||
        th[5] != key.level || get<std::uint32_t>(th + 8) != static_cast<std::uint32_t>(key.tx) ||
        get<std::uint32_t>(th + 12) != static_cast<std::uint32_t>(key.ty) ||
        get<std::uint32_t>(th + 16) != static_cast<std::uint32_t>(tile.width) ||
        get<std::uint32_t>(th + 20) != static_cast<std::uint32_t>(tile.height)) {
        fail("the index disagrees with the tile at byte " + std::to_string(off) +
             " (its own header names another tile or size)");
    }
    const std::uint8_t* src = buf.data() + kTileHeaderBytes;
    const std::size_t srcBytes = stored - kTileHeaderBytes;
    std::vector<std::uint8_t> payload;
    switch (static_cast<TileCodec>(th[6])) {
        case TileCodec::None:
            if (srcBytes != raw) fail("stored size disagrees with the payload size");
            payload.assign(src, src + srcBytes);
            break;
        case TileCodec::Lz4: {
            payload.resize(raw);
            const int n = LZ4_decompress_safe(reinterpret_cast<const char*>(src),
                                              reinterpret_cast<char*>(payload.data()),
                                              static_cast<int>(srcBytes), static_cast<int>(raw));
            if (n != static_cast<int>(raw)) fail("LZ4 payload does not decode (corrupt tile)");
            break;
        }
        case TileCodec::Zstd: {
            payload.resize(raw);
            const std::size_t n = ZSTD_decompress(payload.data(), raw, src, srcBytes);
            if (ZSTD_isError(n) || n != raw) fail("zstd payload does not decode (corrupt tile)");
            break;
        }
        default:
            fail("unknown codec " + std::to_string(th[6]));
    }
    const std::size_t n = static_cast<std::size_t>(tile.width) * tile.height;
    const std::uint8_t* p = payload.data();
    if (key.kind == TileKind::Display) {
        tile.heights.resize(n);
        std::memcpy(tile.heights.data(), p, n * 2);
        p += n * 2;
        tile.colors.resize(n);
        std::memcpy(tile.colors.data(), p, n * 3);
        p += n * 3;
        tile.maxima.resize(static_cast<std::size_t>(tile.width - 1) * (tile.height - 1));
    } else {
        tile.maxima.resize(n);
    }
    std::memcpy(tile.maxima.data(), p, tile.maxima.size() * 2);
    return tile;
}

void TerrainDb::checkLoadable() const {
    if (static_cast<std::size_t>(info_.width) * static_cast<std::size_t>(info_.height) >
        kMaxImageSamples) {
        throw InputError(path_ + ": the map (" + std::to_string(info_.width) + " x " +
                         std::to_string(info_.height) +
                         ") has more than 2^30 samples, the most a map loaded whole holds; "
                         "page it (--cache-mb below its size)");
    }
}

void TerrainDb::checkPageable() const {
    if (static_cast<std::size_t>(info_.width) * static_cast<std::size_t>(info_.height) >
        kMaxPagedSamples) {
        throw InputError(path_ + ": the map (" + std::to_string(info_.width) + " x " +
                         std::to_string(info_.height) +
                         ") has more than 2^36 samples, the most a paged map addresses");
    }
}

TerrainMap TerrainDb::loadMap() const {
    checkLoadable();
    TerrainMap map(info_.width, info_.height, info_.spacingX, info_.spacingY, info_.heightScale,
                   info_.heightOffset);
    const int nx = layout_.tilesX(TileKind::Display, 0), ny = layout_.tilesY(TileKind::Display, 0);
    for (int ty = 0; ty < ny; ++ty) {
        for (int tx = 0; tx < nx; ++tx) {
            const TerrainTile t = readTile(TileKey{TileKind::Display, 0, tx, ty});
            for (int y = 0; y < t.height; ++y) {
                const std::size_t src = static_cast<std::size_t>(y) * t.width;
                const std::size_t dst = map.index(t.x0, t.y0 + y);
                std::copy_n(t.heights.begin() + static_cast<std::ptrdiff_t>(src), t.width,
                            map.rawHeights().begin() + static_cast<std::ptrdiff_t>(dst));
                std::copy_n(t.colors.begin() + static_cast<std::ptrdiff_t>(src), t.width,
                            map.colors().begin() + static_cast<std::ptrdiff_t>(dst));
            }
        }
    }
    map.updateRange();
    Georeference g;
    g.originX = info_.originX;
    g.originY = info_.originY;
    g.crs = info_.crs;
    map.setGeoreference(std::move(g));
    return map;
}

}  // namespace ig
