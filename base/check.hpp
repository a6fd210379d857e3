// Checks for invariants: conditions that hold unless the program itself is wrong.
//
// CHECK(cond) is always compiled; DCHECK(cond) only when NDEBUG is not defined (debug and
// sanitizer builds), for checks on hot paths. A failed check prints the file, line, the
// condition and any streamed context to stderr and aborts: a bug is never turned into an
// exception a caller might catch and carry on from. Bad input from outside (files, flags,
// devices) is not an invariant: it is thrown as base::InputError and reported by the program.
//
//     CHECK(width > 0) << "frame of " << width << " columns";
//     CHECK_LE(first, last);
//     DCHECK_LT(index, size);
#pragma once

#include <sstream>

namespace base {

// Collects the message of a failed check; its destructor prints it and aborts.
class CheckFailure {
  public:
    CheckFailure(const char* file, int line, const char* condition);
    CheckFailure(const CheckFailure&) = delete;
    CheckFailure& operator=(const CheckFailure&) = delete;
    [[noreturn]] ~CheckFailure();

    template <typename T>
    CheckFailure& operator<<(const T& value) {
        message_ << value;
        return *this;
    }

  private:
    std::ostringstream message_;
};

// Lets `cond ? (void)0 : CheckVoidify() & CheckFailure(...) << ...` type-check as void.
struct CheckVoidify {
    void operator&(const CheckFailure&) {}
};

}  // namespace base

#define CHECK(condition)  \
    (condition) ? (void)0 \
                : ::base::CheckVoidify() & ::base::CheckFailure(__FILE__, __LINE__, #condition)

#define BASE_CHECK_OP(a, op, b) CHECK((a)op(b)) << "(" << (a) << " " #op " " << (b) << ") "

#define CHECK_EQ(a, b) BASE_CHECK_OP(a, ==, b)
#define CHECK_NE(a, b) BASE_CHECK_OP(a, !=, b)
#define CHECK_LT(a, b) BASE_CHECK_OP(a, <, b)
#define CHECK_LE(a, b) BASE_CHECK_OP(a, <=, b)
#define CHECK_GT(a, b) BASE_CHECK_OP(a, >, b)
#define CHECK_GE(a, b) BASE_CHECK_OP(a, >=, b)

#ifdef NDEBUG
// Compiled but never evaluated, so the condition stays type-checked and variables it names used.
#define DCHECK(condition) \
    while (false)         \
    CHECK(condition)
#define DCHECK_EQ(a, b) \
    while (false)       \
    CHECK_EQ(a, b)
#define DCHECK_NE(a, b) \
    while (false)       \
    CHECK_NE(a, b)
#define DCHECK_LT(a, b) \
    while (false)       \
    CHECK_LT(a, b)
#define DCHECK_LE(a, b) \
    while (false)       \
    CHECK_LE(a, b)
#define DCHECK_GT(a, b) \
    while (false)       \
    CHECK_GT(a, b)
#define DCHECK_GE(a, b) \
    while (false)       \
    CHECK_GE(a, b)
#else
#define DCHECK(condition) CHECK(condition)
#define DCHECK_EQ(a, b) CHECK_EQ(a, b)
#define DCHECK_NE(a, b) CHECK_NE(a, b)
#define DCHECK_LT(a, b) CHECK_LT(a, b)
#define DCHECK_LE(a, b) CHECK_LE(a, b)
#define DCHECK_GT(a, b) CHECK_GT(a, b)
#define DCHECK_GE(a, b) CHECK_GE(a, b)
#endif
