// What a render asks of the renderer's geometry besides the pose (a host's View Definition).
#pragma once

namespace sim {

// A host's field of view, draw distance and near plane for the run so far (a CIGI View
// Definition), carried with every render request. 0 (the near plane: negative): the renderer's
// geometry's own.
struct RenderView {
    double hfov = 0.0;    // horizontal field of view of the window, radians
    double farM = 0.0;    // draw distance, metres (infinite: none)
    double nearM = -1.0;  // near clipping plane ahead along the view axis, metres (0: none)
};

}  // namespace sim
