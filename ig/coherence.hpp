// The coherence proof (docs/design/ray_casting.md, "Coherence under pitch"): when a ray may
// start where the ray below it stopped. One copy, used by every fast-caster kernel and by the
// stereo second pass.
#pragma once

namespace ig {

// Two rays leave the eye. Per unit of the distance both have travelled (along the map's major
// axis for the caster, horizontally for the stereo pass), the upper one is `climb` higher than
// the lower one and `gap` cells of `cell` metres to its side, where the terrain rises at most
// `slopeBound` per metre. Both sides grow with the distance, so if the climb outruns the most
// the terrain can rise across the gap, the upper ray is above the terrain wherever the lower
// one was, and may start where the lower one stopped. T is double (Clear bool), or a vector
// of doubles (Clear its lanes' mask); the operations and their order are the same in every
// kernel (the images are compared bit for bit). Arguments by reference: no vector ABI.
template <typename T, typename Clear>
[[gnu::always_inline]] inline void testClimb(const T& climb, double slopeBound, double cell,
                                             const T& gap, Clear& clear) {
    clear = climb >= slopeBound * cell * gap;
}

// testClimb for one ray.
[[gnu::always_inline]] inline bool climbsClearOf(double climb, double slopeBound, double cell,
                                                 double gap) {
    bool clear = false;
    testClimb(climb, slopeBound, cell, gap, clear);
    return clear;
}

}  // namespace ig
