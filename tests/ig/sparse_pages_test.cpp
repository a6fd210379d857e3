// Sparse blocks' pages given back and backed many runs at a time (ig/terrain.hpp): the batched
// call and its one-madvise-per-run twin leave the same pages in memory with the same bytes.
#include <sys/mman.h>
#include <sys/utsname.h>

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <vector>

#include "ig/terrain.hpp"

namespace {

constexpr std::size_t kPage = 4096;
constexpr std::size_t kPages = 48;

// Whether each page of the block is in memory (mincore).
std::vector<bool> resident(const std::uint8_t* block) {
    std::vector<unsigned char> v(kPages);
    EXPECT_EQ(mincore(const_cast<std::uint8_t*>(block), kPages * kPage, v.data()), 0);
    std::vector<bool> out(kPages);
    for (std::size_t i = 0; i < kPages; ++i)
        out[i] = (v[i] & 1) != 0;
    return out;
}

std::vector<ig::PageRun> runsOf(const std::uint8_t* block, const std::vector<std::size_t>& pages) {
    std::vector<std::uintptr_t> addresses;
    for (const std::size_t p : pages)
        addresses.push_back(reinterpret_cast<std::uintptr_t>(block) + p * kPage);
    std::vector<ig::PageRun> runs;
    ig::pageRuns(addresses, runs);
    return runs;
}

// Whether the kernel takes any advice from process_madvise on the calling process (6.13).
bool kernelBatches() {
    utsname u{};
    int major = 0, minor = 0;
    if (uname(&u) != 0 || std::sscanf(u.release, "%d.%d", &major, &minor) != 2) return false;
    return major > 6 || (major == 6 && minor >= 13);
}

struct Outcome {
    std::size_t batchedRelease = 0, batchedPopulate = 0;  // runs given to a batched call
    std::vector<bool> afterRelease, afterPopulate;
    std::vector<std::uint8_t> bytes;  // the first byte of each page at the end
};

Outcome releaseThenPopulate(bool batching) {
    ig::setPageBatching(batching);
    auto* block = static_cast<std::uint8_t*>(ig::allocateSparse(kPages * kPage));
    for (std::size_t p = 0; p < kPages; p += 2)
        std::memset(block + p * kPage, static_cast<int>(p + 1), kPage);  // even pages written
    Outcome o;
    // Released: written pages and never-written ones, single and in runs.
    o.batchedRelease = ig::releaseSparsePageRuns(runsOf(block, {2, 3, 4, 10, 20, 21, 22, 23, 40}));
    o.afterRelease = resident(block);
    // Backed: pages given back, never written, and still written (which keep their bytes).
    o.batchedPopulate =
        ig::populateSparsePageRuns(runsOf(block, {1, 4, 5, 6, 7, 8, 12, 21, 33, 47}));
    o.afterPopulate = resident(block);
    for (std::size_t p = 0; p < kPages; ++p)
        o.bytes.push_back(block[p * kPage + kPage - 1]);
    ig::deallocateSparse(block, kPages * kPage);
    ig::setPageBatching(true);
    return o;
}

TEST(SparsePages, PageRunsJoinAdjacentPages) {
    const std::vector<std::uintptr_t> pages{0x10000, 0x11000, 0x12000, 0x14000, 0x20000, 0x21000};
    std::vector<ig::PageRun> runs;
    ig::pageRuns(pages, runs);
    ASSERT_EQ(runs.size(), 3u);
    EXPECT_EQ(runs[0].begin, 0x10000u);
    EXPECT_EQ(runs[0].pages, 3u);
    EXPECT_EQ(runs[1].begin, 0x14000u);
    EXPECT_EQ(runs[1].pages, 1u);
    EXPECT_EQ(runs[2].begin, 0x20000u);
    EXPECT_EQ(runs[2].pages, 2u);
    ig::pageRuns({}, runs);
    EXPECT_TRUE(runs.empty());
}

TEST(SparsePages, BatchedCallsLeaveWhatOneMadviseARunLeaves) {
    const Outcome batched = releaseThenPopulate(true);
    const Outcome each = releaseThenPopulate(false);
    EXPECT_EQ(each.batchedRelease + each.batchedPopulate, 0u);
    if (kernelBatches()) {                       // the batched path itself, where the kernel has it
        EXPECT_EQ(batched.batchedRelease, 4u);   // {2-4}, {10}, {20-23}, {40}
        EXPECT_EQ(batched.batchedPopulate, 6u);  // {1}, {4-8}, {12}, {21}, {33}, {47}
    }
    EXPECT_EQ(batched.afterRelease, each.afterRelease);
    EXPECT_EQ(batched.afterPopulate, each.afterPopulate);
    EXPECT_EQ(batched.bytes, each.bytes);

    // What both must be: written pages stay unless released; released and fresh pages read 0.
    for (std::size_t p = 0; p < kPages; ++p) {
        const bool released = p == 2 || p == 4 || p == 10 || p == 20 || p == 22 || p == 40;
        const bool written = p % 2 == 0 && !released;
        EXPECT_EQ(each.afterRelease[p], written) << "page " << p;
        EXPECT_EQ(each.bytes[p], written ? p + 1 : 0u) << "page " << p;
    }
    // Backed (MADV_POPULATE_WRITE, Linux 5.14: Debian 12 has 6.1), reading zero; the written
    // pages stay.
    for (const std::size_t p : {1u, 4u, 5u, 7u, 21u, 33u, 47u, 0u, 6u, 8u, 12u, 46u})
        EXPECT_TRUE(each.afterPopulate[p]) << "page " << p;
    for (const std::size_t p : {2u, 3u, 10u, 20u, 22u, 40u, 9u})
        EXPECT_FALSE(each.afterPopulate[p]) << "page " << p;
}

}  // namespace
