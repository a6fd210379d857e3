// Where fields go: the sink interface and the factory for "y4m:", "v4l2:", "png:" and "null".
#pragma once

#include <memory>
#include <string>

#include "io/contact_sheet.hpp"
#include "io/video_format.hpp"

namespace io {

// A sink is constructed without touching files or devices; open() does that and reports a bad
// path or device there, before a run starts. Calls return 0 or -errno.
class FrameSink {
  public:
    virtual ~FrameSink() = default;
    // Opens the output for `format`; the sink may adjust the format (V4L2 G_FMT), see format().
    virtual int open(const VideoFormat& format, std::string* error) = 0;
    // Hands one field over; its lines are `format().width` pixels wide.
    virtual int writeField(const FieldBuffer& field) = 0;
    // Finishes the output; a file appears under its name only when this returns 0.
    virtual int close(std::string* error) = 0;
    virtual const VideoFormat& format() const = 0;
};

// spec: "y4m:PATH" (PATH "-" = stdout) | "v4l2:/dev/videoN" | "png:DIR[:EVERY_N]" | "null".
// Returns nullptr and sets `error` on a malformed spec; bad paths are reported by open().
// `overwrite`: a png:DIR that is not empty is written into (else open() refuses it).
std::unique_ptr<FrameSink> makeSink(const std::string& spec, std::string* error,
                                    bool overwrite = false);
// The file or folder a spec writes ("" for v4l2 and null), for the checks made before a run.
std::string sinkPath(const std::string& spec);
// True when the spec writes a folder (png:DIR).
bool sinkWritesFolder(const std::string& spec);

}  // namespace io
