// The error every module throws for bad input from outside (files, flags, devices).
#pragma once

#include <stdexcept>
#include <string>

namespace base {

// Bad input: the message names the input and what is wrong with it. Programs catch it at main,
// print it and exit non-zero.
class InputError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

}  // namespace base
