// Whole text files read in one go, with the reason when they cannot be.
#pragma once

#include <string>

namespace io {

// Reads the file at `path` into `text`. 0, or -errno with the reason in *error (such as "is a
// folder, not a file" or "cannot open: No such file or directory"), for the caller to put
// after the file's name.
int readTextFile(const std::string& path, std::string& text, std::string* error);

}  // namespace io
