// Locks the field process's memory in RAM (mlockall), so no field waits on a page fault.
#pragma once

#include <string>

namespace io {

struct MemoryLock {
    bool locked = false;
    std::string error;  // why not, when not ("Cannot allocate memory (RLIMIT_MEMLOCK 8 MiB)")
};

// mlockall(MCL_CURRENT | MCL_FUTURE): every page mapped now and later is resident and faulted in
// when mapped (buffers reserved before the run are pre-faulted). Refused without the privilege
// or under RLIMIT_MEMLOCK; not attempted under a sanitizer (its shadow memory cannot be locked).
MemoryLock lockAllMemory();

// Bytes of this process's memory locked, from /proc/self/status (VmLck); -1 when unknown.
long long lockedBytes();

}  // namespace io
