// The row batches on four lanes (AVX2): RowBatches<V4> (caster_rows.hpp). This object is
// compiled for AVX2 (ig/CMakeLists.txt) and its kernel is called only where the processor has
// it (base::cpuFeatures). Everything it defines has internal linkage but rows_avx2::kernel()
// (docs/design/multires.md, "One object per instruction set").
#include "ig/fast_column.hpp"

#if VIG_CASTER_PACKETS && defined(__AVX2__)
#include "ig/caster_lanes.hpp"
#include "ig/caster_rows.hpp"

namespace ig::rows_avx2 {

fast::RowKernel kernel() {
    return {4, &fast::RowBatches<fast::V4>::run, &fast::RowBatches<fast::V4>::cast};
}

}  // namespace ig::rows_avx2

#else

namespace ig::rows_avx2 {

fast::RowKernel kernel() {
    return {};
}

}  // namespace ig::rows_avx2

#endif
