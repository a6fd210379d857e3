// Output files, one policy for every program: what a path leads to, how it is written, and the
// checks made on a run's paths before any work starts.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace io {

// What writing to a path will do.
enum class OutputKind {
    Stdout,   // "-": standard output
    File,     // a regular file or a new name: written beside it (PATH.part) and renamed into place
    InPlace,  // an existing character or block device or FIFO: written where it is, never replaced
};

struct OutputTarget {
    OutputKind kind = OutputKind::File;
    std::string path;  // where the bytes go: the given path with every symlink followed
};

// Resolves `path` as the write will see it. A symlink is followed to what it names (a dangling
// one: the file is created where it points). Refused, with -errno and a message naming the path
// and the reason: an empty path, a folder, a socket, a missing parent folder, a loop of links.
int resolveOutput(const std::string& path, OutputTarget& target, std::string* error);

// Checks, before a long run, that `path` can be written later: resolves it, and for a file
// makes and removes a probe in its folder (permissions, read-only file systems); a device or
// FIFO must be writable. Nothing is left behind and an existing file is untouched.
int checkOutputPath(const std::string& path, std::string* error);

// A file being written under the policy above. For OutputKind::File the bytes go to PATH.part
// beside the final file, renamed into place by commit(); a file not committed (a failed run,
// destruction, a second SIGINT/SIGTERM) leaves no .part behind and the old file untouched.
class OutputFile {
  public:
    OutputFile() = default;
    ~OutputFile();
    OutputFile(const OutputFile&) = delete;
    OutputFile& operator=(const OutputFile&) = delete;

    // 0 or -errno (message in *error naming the path). A FIFO with no reader is refused rather
    // than waited on.
    int open(const std::string& path, std::string* error);
    // A stream of fixed-size records after a header (Y4M frames): on a second stop signal the
    // file is cut to its last whole record and renamed into place instead of being dropped.
    void keepWholeRecordsOnAbort(std::uint64_t headerBytes, std::uint64_t recordBytes);
    std::FILE* get() const { return file_; }
    bool isOpen() const { return file_ != nullptr; }
    OutputKind kind() const { return target_.kind; }
    const std::string& path() const { return path_; }
    // Flushes, syncs a regular file, closes, renames into place. 0 or -errno (message names the
    // path and the reason).
    int commit(std::string* error);
    // Closes and removes what was written (a file in place is only closed).
    void discard();

  private:
    std::string path_, partPath_;
    OutputTarget target_;
    std::FILE* file_ = nullptr;
    int abortSlot_ = -1;
};

// Writes `text` to `path` under the policy; 0 or -errno with a message naming the path.
int writeTextFile(const std::string& path, const std::string& text, std::string* error);

// ---- A program's paths, checked together before any work starts ---------------------------

enum class PathRole { Input, Output, OutputFolder };

struct PathUse {
    std::string flag;  // "--out", "--height", ...
    std::string path;  // as given; empty: not used
    PathRole role = PathRole::Output;
};

// Refuses, naming both flags: an output that is the same file as an input or as another output
// (symlinks and other spellings of one path included; devices such as /dev/null may be shared
// by outputs), and standard output ("-") named by more than one output. Each output file is
// checked with checkOutputPath. Throws base::InputError.
void checkRunPaths(const std::vector<PathUse>& uses);
// True when some output of `uses` is standard output: nothing else may print there.
bool usesStdout(const std::vector<PathUse>& uses);
// Throwing wrappers for programs: base::InputError naming `flag`.
void writeTextOutput(const std::string& flag, const std::string& path, const std::string& text);

// A folder output (png:DIR) must be missing or empty, unless `overwrite`: frames of an earlier
// run must not mix with this one's. 0, or -errno with a message.
int checkOutputFolder(const std::string& dir, bool overwrite, std::string* error);

}  // namespace io
