#include "io/output_file.hpp"

#include "base/error.hpp"
#include "io/stop_signals.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

namespace io {
namespace {

int fail(std::string* error, const std::string& message, int rc) {
    if (error) *error = message;
    return rc;
}

std::string reason(int err) {
    return std::strerror(err);
}

std::string parentOf(const std::string& path) {
    const std::string dir = std::filesystem::path(path).parent_path().string();
    return dir.empty() ? "." : dir;
}

}  // namespace

int resolveOutput(const std::string& path, OutputTarget& target, std::string* error) {
    if (path.empty()) return fail(error, "empty path", -EINVAL);
    if (path == "-") {
        target = {OutputKind::Stdout, "-"};
        return 0;
    }
    std::string p = path;
    for (int hops = 0;; ++hops) {
        struct stat st {};
        if (::lstat(p.c_str(), &st) != 0) {
            const int err = errno;
            if (err != ENOENT) return fail(error, path + ": " + reason(err), -err);
            // A new file: its folder must exist.
            const std::string dir = parentOf(p);
            struct stat dst {};
            if (::stat(dir.c_str(), &dst) != 0 || !S_ISDIR(dst.st_mode)) {
                return fail(error, path + ": folder " + dir + " does not exist", -ENOENT);
            }
            target = {OutputKind::File, p};
            return 0;
        }
        if (S_ISLNK(st.st_mode)) {
            if (hops >= 40)
                return fail(error, path + ": too many levels of symbolic links", -ELOOP);
            std::string link(static_cast<std::size_t>(st.st_size > 0 ? st.st_size : 4096) + 1,
                             '\0');
            const ssize_t n = ::readlink(p.c_str(), link.data(), link.size());
            if (n < 0) {
                const int err = errno;
                return fail(error, path + ": " + reason(err), -err);
            }
            link.resize(static_cast<std::size_t>(n));
            p = (!link.empty() && link[0] == '/')
                    ? link
                    : (std::filesystem::path(parentOf(p)) / link).string();
            continue;
        }
        if (S_ISDIR(st.st_mode)) return fail(error, path + ": is a folder, not a file", -EISDIR);
        if (S_ISSOCK(st.st_mode)) return fail(error, path + ": is a socket, not a file", -ENXIO);
        if (S_ISREG(st.st_mode)) {
            target = {OutputKind::File, p};
        } else {
            target = {OutputKind::InPlace, p};  // character or block device, FIFO
        }
        return 0;
    }
}

int checkOutputPath(const std::string& path, std::string* error) {
    OutputTarget t;
    if (const int rc = resolveOutput(path, t, error); rc != 0) return rc;
    if (t.kind == OutputKind::Stdout) return 0;
    if (t.kind == OutputKind::InPlace) {
        if (::access(t.path.c_str(), W_OK) != 0) {
            const int err = errno;
            return fail(error, path + ": cannot write: " + reason(err), -err);
        }
        return 0;
    }
    // A file of our own made and removed again where the write will go.
    const std::string probe = t.path + ".part";
    const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0) {
        const int err = errno;
        if (err == EEXIST) return 0;  // left by an earlier run; the write replaces it
        return fail(error,
                    path + ": cannot create files in " + parentOf(t.path) + ": " + reason(err),
                    -err);
    }
    ::close(fd);
    ::unlink(probe.c_str());
    return 0;
}

// ---- OutputFile ------------------------------------------------------------------------------

OutputFile::~OutputFile() {
    discard();
}

int OutputFile::open(const std::string& path, std::string* error) {
    if (file_) return fail(error, path + ": already open", -EBUSY);
    path_ = path;
    if (const int rc = resolveOutput(path, target_, error); rc != 0) return rc;
    if (target_.kind == OutputKind::Stdout) {
        file_ = stdout;
        return 0;
    }
    int fd = -1;
    if (target_.kind == OutputKind::InPlace) {
        // A FIFO with no reader fails at once (ENXIO) instead of blocking the run.
        fd = ::open(target_.path.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
        if (fd < 0) {
            const int err = errno;
            if (err == ENXIO) {
                return fail(error, path + ": a FIFO with no reader (start the reader first)",
                            -ENXIO);
            }
            return fail(error, path + ": cannot open for writing: " + reason(err), -err);
        }
        const int flags = ::fcntl(fd, F_GETFL);
        if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
    } else {
        partPath_ = target_.path + ".part";
        fd = ::open(partPath_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
        if (fd < 0) {
            const int err = errno;
            return fail(error, path + ": cannot create " + partPath_ + ": " + reason(err), -err);
        }
        abortSlot_ = registerUnfinishedOutput(fd, partPath_.c_str(), nullptr, 0, 0);
    }
    file_ = ::fdopen(fd, "wb");
    if (!file_) {
        const int err = errno;
        ::close(fd);
        discard();
        return fail(error, path + ": " + reason(err), -err);
    }
    return 0;
}

void OutputFile::keepWholeRecordsOnAbort(std::uint64_t headerBytes, std::uint64_t recordBytes) {
    if (!file_ || target_.kind != OutputKind::File) return;
    unregisterUnfinishedOutput(abortSlot_);
    abortSlot_ = registerUnfinishedOutput(::fileno(file_), partPath_.c_str(), target_.path.c_str(),
                                          headerBytes, recordBytes);
}

int OutputFile::commit(std::string* error) {
    if (!file_) return fail(error, path_ + ": not open", -EBADF);
    if (file_ == stdout) {
        file_ = nullptr;
        if (std::fflush(stdout) != 0) {
            const int err = errno ? errno : EIO;
            return fail(error, "standard output: write failed: " + reason(err), -err);
        }
        return 0;
    }
    int err = 0;
    if (std::fflush(file_) != 0 || std::ferror(file_)) err = errno ? errno : EIO;
    if (err == 0 && target_.kind == OutputKind::File && ::fsync(::fileno(file_)) != 0) err = errno;
    unregisterUnfinishedOutput(abortSlot_);
    abortSlot_ = -1;
    if (std::fclose(file_) != 0 && err == 0) err = errno ? errno : EIO;
    file_ = nullptr;
    if (target_.kind == OutputKind::File) {
        if (err == 0 && ::rename(partPath_.c_str(), target_.path.c_str()) != 0) err = errno;
        if (err != 0) ::unlink(partPath_.c_str());
    }
    if (err != 0) return fail(error, path_ + ": write failed: " + reason(err), -err);
    return 0;
}

void OutputFile::discard() {
    unregisterUnfinishedOutput(abortSlot_);
    abortSlot_ = -1;
    if (!file_) return;
    if (file_ == stdout) {
        std::fflush(stdout);
        file_ = nullptr;
        return;
    }
    std::fclose(file_);
    file_ = nullptr;
    if (target_.kind == OutputKind::File) ::unlink(partPath_.c_str());
}

int writeTextFile(const std::string& path, const std::string& text, std::string* error) {
    OutputFile out;
    if (const int rc = out.open(path, error); rc != 0) return rc;
    if (std::fwrite(text.data(), 1, text.size(), out.get()) != text.size()) {
        const int err = errno ? errno : EIO;
        out.discard();
        return fail(error, path + ": write failed: " + reason(err), -err);
    }
    return out.commit(error);
}

// ---- A run's paths ---------------------------------------------------------------------------

namespace {

// Identity of what a path names: device and inode when it exists, else its canonical spelling.
struct PathKey {
    bool exists = false;
    bool charDevice = false;
    dev_t dev = 0;
    ino_t ino = 0;
    std::string canonical;
    bool operator==(const PathKey& o) const {
        return exists == o.exists &&
               (exists ? dev == o.dev && ino == o.ino : canonical == o.canonical);
    }
};

PathKey keyOf(const std::string& path) {
    PathKey k;
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0) {
        k.exists = true;
        k.charDevice = S_ISCHR(st.st_mode);
        k.dev = st.st_dev;
        k.ino = st.st_ino;
        return k;
    }
    std::error_code ec;
    OutputTarget t;
    const std::string resolved = resolveOutput(path, t, nullptr) == 0 ? t.path : path;
    k.canonical = std::filesystem::weakly_canonical(std::filesystem::absolute(resolved, ec), ec)
                      .lexically_normal()
                      .string();
    return k;
}

}  // namespace

void checkRunPaths(const std::vector<PathUse>& uses) {
    const PathUse* stdoutUser = nullptr;
    std::vector<std::pair<const PathUse*, PathKey>> seen;
    for (const PathUse& u : uses) {
        if (u.path.empty()) continue;
        if (u.role != PathRole::Input && u.path == "-") {
            if (stdoutUser) {
                throw base::InputError(u.flag + " -: standard output is already taken by " +
                                       stdoutUser->flag + "; give one of them a file");
            }
            stdoutUser = &u;
            continue;
        }
        if (u.role == PathRole::Input && u.path == "-") continue;
        if (u.role == PathRole::Output) {
            std::string error;
            if (checkOutputPath(u.path, &error) != 0) throw base::InputError(u.flag + " " + error);
        }
        const PathKey key = keyOf(u.path);
        for (const auto& [other, otherKey] : seen) {
            if (!(key == otherKey)) continue;
            const bool bothOutputs = u.role != PathRole::Input && other->role != PathRole::Input;
            if (bothOutputs && key.charDevice) continue;  // /dev/null for several outputs
            if (u.role == PathRole::Input && other->role == PathRole::Input) continue;
            const PathUse& in = other->role == PathRole::Input ? *other : u;
            const PathUse& out = other->role == PathRole::Input ? u : *other;
            if (in.role == PathRole::Input) {
                throw base::InputError(out.flag + " " + out.path +
                                       ": is the same file as the input " + in.flag + " " +
                                       in.path + "; it would be overwritten");
            }
            throw base::InputError(u.flag + " " + u.path + ": is the same file as " + other->flag +
                                   " " + other->path + "; give each output its own path");
        }
        seen.emplace_back(&u, key);
    }
}

bool usesStdout(const std::vector<PathUse>& uses) {
    for (const PathUse& u : uses) {
        if (u.role != PathRole::Input && u.path == "-") return true;
    }
    return false;
}

void writeTextOutput(const std::string& flag, const std::string& path, const std::string& text) {
    std::string error;
    if (writeTextFile(path, text, &error) != 0) throw base::InputError(flag + " " + error);
}

int checkOutputFolder(const std::string& dir, bool overwrite, std::string* error) {
    struct stat st {};
    if (::stat(dir.c_str(), &st) != 0) {
        const int err = errno;
        if (err == ENOENT) return 0;  // made by the sink
        return fail(error, dir + ": " + reason(err), -err);
    }
    if (!S_ISDIR(st.st_mode)) return fail(error, dir + ": is not a folder", -ENOTDIR);
    if (overwrite) return 0;
    DIR* d = ::opendir(dir.c_str());
    if (!d) {
        const int err = errno;
        return fail(error, dir + ": cannot read the folder: " + reason(err), -err);
    }
    bool empty = true;
    while (const dirent* e = ::readdir(d)) {
        if (std::strcmp(e->d_name, ".") != 0 && std::strcmp(e->d_name, "..") != 0) {
            empty = false;
            break;
        }
    }
    ::closedir(d);
    if (!empty) {
        return fail(error,
                    dir +
                        ": the folder is not empty (frames of another run would mix with this "
                        "one's); empty it, name a new folder, or give --overwrite",
                    -EEXIST);
    }
    return 0;
}

}  // namespace io
