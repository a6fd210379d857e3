#include "base/cpu_features.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <thread>
#include <vector>

namespace {

TEST(CpuFeatures, DetectedOnceAndTheSameObjectAfterwards) {
    const base::CpuFeatures* first = &base::cpuFeatures();
    std::vector<std::thread> threads;
    std::vector<const base::CpuFeatures*> seen(4, nullptr);
    for (int i = 0; i < 4; ++i)
        threads.emplace_back([&seen, i] { seen[i] = &base::cpuFeatures(); });
    for (std::thread& t : threads)
        t.join();
    for (const base::CpuFeatures* p : seen)
        EXPECT_EQ(p, first);
}

TEST(CpuFeatures, WiderSetsImplyTheNarrowerOnes) {
    const base::CpuFeatures& f = base::cpuFeatures();
    // Every processor with AVX-512 F/DQ/VL/BW has AVX2; VBMI is reported only on top of them.
    if (f.avx512) {
        EXPECT_TRUE(f.avx2);
    }
    if (f.avx512vbmi) {
        EXPECT_TRUE(f.avx512);
    }
#if !defined(__x86_64__)
    EXPECT_FALSE(f.avx2 || f.fma || f.avx512 || f.avx512vbmi);
#endif
}

TEST(CpuFeatures, AgreeWithTheCompilersView) {
    if (std::getenv("VIG_CPU_DISABLE") != nullptr) GTEST_SKIP() << "features hidden";
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
    EXPECT_EQ(base::cpuFeatures().avx2, static_cast<bool>(__builtin_cpu_supports("avx2")));
    EXPECT_EQ(base::cpuFeatures().fma, static_cast<bool>(__builtin_cpu_supports("fma")));
#else
    GTEST_SKIP() << "no x86-64 feature detection in this build";
#endif
}

}  // namespace

namespace {

TEST(CpuFeatures, DisablingAFeatureHidesTheWiderOnes) {
    const base::CpuFeatures all{true, true, true, true};
    base::CpuFeatures f = base::withDisabled(all, "avx512");
    EXPECT_TRUE(f.avx2 && f.fma);
    EXPECT_FALSE(f.avx512 || f.avx512vbmi);
    f = base::withDisabled(all, "avx2");
    EXPECT_FALSE(f.avx2 || f.fma || f.avx512 || f.avx512vbmi);
    f = base::withDisabled(all, "fma,avx512vbmi,unknown");
    EXPECT_TRUE(f.avx2 && f.avx512);
    EXPECT_FALSE(f.fma || f.avx512vbmi);
    f = base::withDisabled(all, "");
    EXPECT_TRUE(f.avx2 && f.fma && f.avx512 && f.avx512vbmi);
}

}  // namespace
