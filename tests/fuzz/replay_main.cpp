// Runs a fuzz target without libFuzzer: every file of the corpus folders given, then a bounded
// number of deterministic mutations of them. The ordinary (gcc) build and its sanitizer builds
// run the fuzz targets this way in the test suite; docs/design/fuzzing.md.
//
//   fuzz_X CORPUS_DIR... [--mutations N] [--seed S] [--max-len BYTES] [--save K FILE]
//
// --save writes mutation K (numbered from 0, as in a failure's report) to FILE instead of
// running, to reproduce a failure under a debugger or with libFuzzer.
#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

// Present in sanitizer runtimes: called when a sanitizer reports an error and the process dies.
extern "C" void __sanitizer_set_death_callback(void (*callback)()) __attribute__((weak));

namespace {

using Bytes = std::vector<std::uint8_t>;

// What runs now, for the report when it brings the process down.
char gCurrent[512] = "nothing";

void reportCurrent() {
    const char prefix[] = "\nfuzz replay: failed on ";
    [[maybe_unused]] ssize_t n = ::write(2, prefix, sizeof prefix - 1);
    n = ::write(2, gCurrent, std::strlen(gCurrent));
    n = ::write(2, "\n", 1);
}

void onSignal(int sig) {
    reportCurrent();
    std::signal(sig, SIG_DFL);
    std::raise(sig);
}

Bytes readFile(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return Bytes(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Byte values that often sit on a parser's edges.
constexpr std::uint8_t kInteresting[] = {0x00, 0x01, 0x7f, 0x80, 0xff, '\n', ',',  '#', ' ',
                                         '-',  '+',  '.',  'e',  '0',  '9',  0xfe, 0x10};

// One mutation of `input` (corpus[] for splices), libFuzzer's kinds in small.
Bytes mutate(const std::vector<Bytes>& corpus, std::mt19937_64& rng, std::size_t maxLen) {
    auto pick = [&](std::size_t n) { return n == 0 ? 0 : static_cast<std::size_t>(rng() % n); };
    Bytes b = corpus[pick(corpus.size())];
    const int steps = 1 + static_cast<int>(pick(4));
    for (int s = 0; s < steps; ++s) {
        switch (pick(9)) {
            case 0:  // flip a bit
                if (!b.empty()) b[pick(b.size())] ^= static_cast<std::uint8_t>(1u << pick(8));
                break;
            case 1:  // set a byte to an edge value
                if (!b.empty()) b[pick(b.size())] = kInteresting[pick(std::size(kInteresting))];
                break;
            case 2:  // set a byte to anything
                if (!b.empty()) b[pick(b.size())] = static_cast<std::uint8_t>(rng());
                break;
            case 3: {  // insert a few bytes
                const std::size_t n = 1 + pick(8);
                const std::size_t at = pick(b.size() + 1);
                Bytes ins(n);
                for (auto& c : ins)
                    c = pick(2) ? kInteresting[pick(std::size(kInteresting))]
                                : static_cast<std::uint8_t>(rng());
                b.insert(b.begin() + static_cast<std::ptrdiff_t>(at), ins.begin(), ins.end());
                break;
            }
            case 4: {  // delete a range
                if (b.empty()) break;
                const std::size_t at = pick(b.size());
                const std::size_t n = 1 + pick(std::min<std::size_t>(b.size() - at, 16));
                b.erase(b.begin() + static_cast<std::ptrdiff_t>(at),
                        b.begin() + static_cast<std::ptrdiff_t>(at + n));
                break;
            }
            case 5:  // truncate
                b.resize(pick(b.size() + 1));
                break;
            case 6: {  // splice: this one's head, another's tail
                const Bytes& o = corpus[pick(corpus.size())];
                const std::size_t cut = pick(b.size() + 1), from = pick(o.size() + 1);
                b.resize(cut);
                b.insert(b.end(), o.begin() + static_cast<std::ptrdiff_t>(from), o.end());
                break;
            }
            case 7: {  // copy a chunk of itself elsewhere (repeats, long lines)
                if (b.empty()) break;
                const std::size_t from = pick(b.size());
                const std::size_t n = 1 + pick(std::min<std::size_t>(b.size() - from, 64));
                const Bytes chunk(b.begin() + static_cast<std::ptrdiff_t>(from),
                                  b.begin() + static_cast<std::ptrdiff_t>(from + n));
                const std::size_t times = 1 + pick(pick(2) ? 4 : 256);
                const std::size_t at = pick(b.size() + 1);
                for (std::size_t t = 0; t < times; ++t)
                    b.insert(b.begin() + static_cast<std::ptrdiff_t>(at), chunk.begin(),
                             chunk.end());
                break;
            }
            default: {  // a 16- or 32-bit field set to an edge value (sizes in headers)
                if (b.size() < 4) break;
                const std::size_t at = pick(b.size() - 3);
                const std::uint32_t values[] = {0,      1,      0x7fffffff, 0xffffffff,
                                                0x8000, 0xffff, 30000,      65500};
                const std::uint32_t v = values[pick(std::size(values))];
                const std::size_t width = pick(2) ? 2 : 4;
                for (std::size_t k = 0; k < width; ++k)  // big-endian, as PNG and JPEG store
                    b[at + k] = static_cast<std::uint8_t>(v >> (8 * (width - 1 - k)));
                break;
            }
        }
    }
    if (b.size() > maxLen) b.resize(maxLen);
    return b;
}

int usage(const char* self) {
    std::fprintf(stderr,
                 "usage: %s CORPUS_DIR... [--mutations N] [--seed S] [--max-len BYTES] "
                 "[--save K FILE]\n",
                 self);
    return 2;
}

}  // namespace

int main(int argc, char** argv) {
    std::vector<std::filesystem::path> dirs;
    long mutations = 2000, save = -1;
    std::uint64_t seed = 1;
    std::size_t maxLen = 64 * 1024;
    std::string saveFile;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const bool hasValue = i + 1 < argc;
        if (a == "--mutations" && hasValue) {
            mutations = std::strtol(argv[++i], nullptr, 10);
        } else if (a == "--seed" && hasValue) {
            seed = std::strtoull(argv[++i], nullptr, 10);
        } else if (a == "--max-len" && hasValue) {
            maxLen = std::strtoull(argv[++i], nullptr, 10);
        } else if (a == "--save" && i + 2 < argc) {
            save = std::strtol(argv[++i], nullptr, 10);
            saveFile = argv[++i];
        } else if (!a.empty() && a[0] != '-') {
            dirs.emplace_back(a);
        } else {
            return usage(argv[0]);
        }
    }
    if (dirs.empty()) return usage(argv[0]);

    std::vector<std::filesystem::path> files;
    for (const auto& dir : dirs) {
        std::error_code ec;
        for (const auto& e : std::filesystem::directory_iterator(dir, ec))
            if (e.is_regular_file()) files.push_back(e.path());
        if (ec) {
            std::fprintf(stderr, "fuzz replay: %s: %s\n", dir.c_str(), ec.message().c_str());
            return 2;
        }
    }
    std::sort(files.begin(), files.end());
    if (files.empty()) {
        std::fprintf(stderr, "fuzz replay: no corpus files\n");
        return 2;
    }
    std::vector<Bytes> corpus;
    for (const auto& f : files)
        corpus.push_back(readFile(f));

    std::mt19937_64 rng(seed);
    if (save >= 0) {
        Bytes b;
        for (long k = 0; k <= save; ++k)
            b = mutate(corpus, rng, maxLen);
        std::ofstream(saveFile, std::ios::binary)
            .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
        std::printf("fuzz replay: mutation %ld (%zu bytes) written to %s\n", save, b.size(),
                    saveFile.c_str());
        return 0;
    }

    if (__sanitizer_set_death_callback) __sanitizer_set_death_callback(reportCurrent);
    for (const int sig : {SIGSEGV, SIGABRT, SIGFPE, SIGILL, SIGBUS})
        std::signal(sig, onSignal);

    const auto start = std::chrono::steady_clock::now();
    for (std::size_t k = 0; k < corpus.size(); ++k) {
        std::snprintf(gCurrent, sizeof gCurrent, "corpus file %s", files[k].c_str());
        LLVMFuzzerTestOneInput(corpus[k].data(), corpus[k].size());
    }
    for (long k = 0; k < mutations; ++k) {
        const Bytes b = mutate(corpus, rng, maxLen);
        std::snprintf(gCurrent, sizeof gCurrent,
                      "mutation %ld (seed %llu; --save %ld FILE writes it)", k,
                      static_cast<unsigned long long>(seed), k);
        LLVMFuzzerTestOneInput(b.data(), b.size());
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf(
        "fuzz replay: %zu corpus files and %ld mutations (seed %llu) in %.2f s, no failure\n",
        corpus.size(), mutations, static_cast<unsigned long long>(seed), seconds);
    return 0;
}
