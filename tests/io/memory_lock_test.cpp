#include "io/memory_lock.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <vector>

namespace {

// In a child (the lock lasts for the process): either the memory is locked, and the kernel
// counts locked pages including a buffer allocated afterwards (MCL_FUTURE faults it in), or the
// refusal says why. Exit status: 0 locked as claimed, 1 refused with a reason, 2 inconsistent.
TEST(MemoryLock, LockedOrRefusedWithAReason) {
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        const io::MemoryLock lock = io::lockAllMemory();
        if (!lock.locked) _exit(lock.error.empty() ? 2 : 1);
        const long long before = io::lockedBytes();
        std::vector<char> buffer(64 << 20);  // never touched: locked pages are faulted in
        const long long after = io::lockedBytes();
        _exit(before > 0 && after >= before + (48 << 20) && !buffer.empty() ? 0 : 2);
    }
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_NE(WEXITSTATUS(status), 2);
    RecordProperty("locked", WEXITSTATUS(status) == 0 ? "yes" : "refused");
}

}  // namespace
