// What a render asks of the renderer's geometry besides the pose (a host's View Definition).
#pragma once

namespace sim {

// A host's field of view and draw distance for the run so far (a CIGI View Definition), carried
// with every render request. 0: the renderer's geometry's own.
struct RenderView {
    double hfov = 0.0;  // horizontal field of view of the window, radians
    double farM = 0.0;  // draw distance, metres (infinite: none)
};

}  // namespace sim
