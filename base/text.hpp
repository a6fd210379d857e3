// Text for messages about outside input: quoted and bounded, numbers printed readably.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace base {

// `text` in single quotes for an error message: bytes outside printable ASCII (and the quote and
// backslash) written as \xNN, at most `limit` bytes of the input shown; longer input is cut
// and the message says how long it was ("'abc...' (10485760 bytes)").
std::string quoted(std::string_view text, std::size_t limit = 200);

// A number as a person reads it: up to `digits` significant digits, no trailing zeros, an
// exponent only for very large or small magnitudes ("1e+300", "0.25", "-3", "nan", "inf").
std::string number(double value, int digits = 6);

}  // namespace base
