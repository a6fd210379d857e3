// Counts every allocation of a test program: the program is linked with
// tests/common/counting_new.cpp (it replaces the global operator new and delete; see
// tests/CMakeLists.txt), and a test compares gAllocations before and after the code that must
// not allocate.
#pragma once

#include <atomic>
#include <cstdlib>
#include <new>

inline std::atomic<std::size_t> gAllocations{0};
// The same counted per thread: allocations made by the thread that reads it.
inline thread_local std::size_t tThreadAllocations = 0;
