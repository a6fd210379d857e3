// Node skipping for the fast caster's multiresolution marches: how many major grid lines a
// fan of rays may pass over the max-height pyramid's nodes without sampling the surface.
// Internal to the fast caster (compiled with its floating-point flags).
#pragma once

#include "ig/pyramid.hpp"

#include <algorithm>

namespace ig::fast {

// A march on major lines tries to pass max-height nodes (skipNodes) once it has sampled
// kSkipAfter lines without ending, starting with nodes of 2^kSkipFirstLevel cells, and again
// kSkipRetry lines after a try that passed none, twice as many after each further one (rays
// grazing far over the terrain would otherwise sample every line up to the level-0
// distance; rays close over it would try in vain).
constexpr long kSkipAfter = 16, kSkipRetry = 8;
constexpr int kSkipFirstLevel = 4;

// A fan of rays from the eye, in major-axis form: at major distance u >= 0 from the eye (grid
// units) each ray is at height eyeRaw + dzr * u (raw height units) with dzr >= dzrLow, and at
// minor coordinate en + rn * u with rn in [rnLo, rnHi]; the eye is at (em, en) in grid units
// along the major and minor axes.
struct RayFan {
    double em, en;
    double eyeRaw, dzrLow;
    double rnLo, rnHi;
};

// Lines a fan of rays from the eye may pass after major line lineA without a sample (at most
// maxLines): lines up to the far side of the max-height node (of level j, the level tried
// first, then finer ones down to 2) that the line after A lies in along the major axis, where
// over the nodes the fan's tracks cross every ray stays above the node maxima, and so above
// every line sample. The expressions are the march's, so their rounding is too. 0 when no
// level gives any; j is left at the next level to try.
template <bool kMajorX>
[[gnu::always_inline]] inline long skipNodes(const TerrainPyramid& pyr, int& j, long lineA, int sgn,
                                             long maxLines, const RayFan& fan) {
    const double em = fan.em, en = fan.en, eyeRaw = fan.eyeRaw, dzrLow = fan.dzrLow,
                 rnLo = fan.rnLo, rnHi = fan.rnHi;
    const int top = pyr.nodeLevelCount() - 1;
    const double sgnD = sgn;
    const double uA = (static_cast<double>(lineA) - em) * sgnD;
    for (j = std::min(j, top); j >= 2; --j) {
        const long node = (lineA + sgn) >> j;
        const long end = sgn > 0 ? (node + 1) << j : node << j;
        const long lines = std::min((end - lineA) * sgn, maxLines);
        if (lines < 1) return 0;
        const double uE = (static_cast<double>(lineA + sgn * lines) - em) * sgnD;
        const double low = std::min(eyeRaw + dzrLow * uA, eyeRaw + dzrLow * uE);
        const double lo = std::min(en + rnLo * uA, en + rnLo * uE);
        const double hi = std::max(en + rnHi * uA, en + rnHi * uE);
        const int majorNodes = kMajorX ? pyr.nodesX(j) : pyr.nodesY(j);
        const int minorNodes = kMajorX ? pyr.nodesY(j) : pyr.nodesX(j);
        const int mn = static_cast<int>(std::clamp<long>(node, 0, majorNodes - 1));
        // (The tracks lie inside the map here: lo >= 0, so truncation is the floor.)
        const int n0 = std::clamp(static_cast<int>(lo) >> j, 0, minorNodes - 1);
        const int n1 = std::clamp(static_cast<int>(hi) >> j, 0, minorNodes - 1);
        if (n1 - n0 > 3) continue;  // a wide fan: finer nodes
        int bound = 0;
        for (int n = n0; n <= n1; ++n)
            bound =
                std::max<int>(bound, kMajorX ? pyr.nodeMaxRaw(j, mn, n) : pyr.nodeMaxRaw(j, n, mn));
        if (low > bound) {
            j = std::min(j + 1, top);
            return lines;
        }
    }
    j = 2;
    return 0;
}

}  // namespace ig::fast
