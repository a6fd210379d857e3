// The running processor's vector instruction sets, detected once.
#pragma once

#include <string_view>

namespace base {

// What the processor running this program can execute. All false off x86-64 (or with a
// compiler without __builtin_cpu_supports): the portable code paths run there.
struct CpuFeatures {
    bool avx2 = false;
    bool fma = false;
    // AVX-512 F, DQ, VL and BW together (what the vector kernels' AVX-512 code uses).
    bool avx512 = false;
    // AVX-512 VBMI (byte permutes), in addition to the above.
    bool avx512vbmi = false;
};

// Detected on the first call, then the same object. Call it from code compiled for the
// baseline instruction set only: a kernel compiled for a feature must never test for it.
// The environment variable VIG_CPU_DISABLE (a comma-separated list, see withDisabled) hides
// features from the program, to run the paths of a smaller processor on a larger one.
const CpuFeatures& cpuFeatures();

// `f` less the features named in `list` ("avx2", "fma", "avx512", "avx512vbmi", comma
// separated; unknown names are ignored). Hiding a feature hides those that imply it: avx2
// hides fma and AVX-512 too, avx512 hides VBMI.
CpuFeatures withDisabled(CpuFeatures f, std::string_view list);

}  // namespace base
