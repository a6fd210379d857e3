#include "base/cpu_features.hpp"

#include <cstdlib>

namespace base {

namespace {

CpuFeatures detect() {
    CpuFeatures f;
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
    __builtin_cpu_init();
    f.avx2 = __builtin_cpu_supports("avx2");
    f.fma = __builtin_cpu_supports("fma");
    f.avx512 = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
               __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512bw");
    f.avx512vbmi = f.avx512 && __builtin_cpu_supports("avx512vbmi");
#endif
    if (const char* disabled = std::getenv("VIG_CPU_DISABLE")) f = withDisabled(f, disabled);
    return f;
}

}  // namespace

CpuFeatures withDisabled(CpuFeatures f, std::string_view list) {
    while (!list.empty()) {
        const std::size_t comma = list.find(',');
        const std::string_view name = list.substr(0, comma);
        list = comma == std::string_view::npos ? std::string_view() : list.substr(comma + 1);
        if (name == "avx2") f.avx2 = f.fma = f.avx512 = f.avx512vbmi = false;
        if (name == "fma") f.fma = false;
        if (name == "avx512") f.avx512 = f.avx512vbmi = false;
        if (name == "avx512vbmi") f.avx512vbmi = false;
    }
    return f;
}

const CpuFeatures& cpuFeatures() {
    static const CpuFeatures features = detect();
    return features;
}

}  // namespace base
