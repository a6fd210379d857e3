// SIGINT and SIGTERM for long-running programs: the first asks the run to stop cleanly, the
// second ends the process at once with every output file still valid.
#pragma once

#include <atomic>
#include <cstdint>

namespace io {

// Installs the handlers. After the first signal stopRequested() is true: the run finishes its
// current field, closes and renames its outputs, writes its reports and exits with
// exitStatusForStop(). A second signal cuts every registered record stream to its last whole
// record, renames it into place, removes every other unfinished output and exits with 128 + the
// signal. `endAtOnce` (batch programs whose files are all written at the end): the first signal
// already does what the second does.
void installStopSignals(bool endAtOnce = false);
bool stopRequested();
// The flag itself, for loops that poll it.
const std::atomic<bool>& stopFlag();
// The first signal received, 0 when none.
int stopSignalNumber();
// 128 + the first signal (130 for SIGINT, 143 for SIGTERM), 0 when none was received.
int exitStatusForStop();
// Asks for a stop as a signal would (tests).
void requestStop(int signal);
// Clears the stop request (tests only).
void resetStopForTests();

// Outputs under way, for the second signal. A record stream (headerBytes, recordBytes > 0) is
// cut to whole records and renamed to `finalPath`; any other entry's `partPath` is removed.
// Paths longer than the registry holds are not registered (-1). Returns a slot for unregister.
int registerUnfinishedOutput(int fd, const char* partPath, const char* finalPath,
                             std::uint64_t headerBytes, std::uint64_t recordBytes);
void unregisterUnfinishedOutput(int slot);

}  // namespace io
