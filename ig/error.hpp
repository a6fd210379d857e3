// The error every module throws for bad input from outside (files, flags, devices).
#pragma once

#include "base/error.hpp"

namespace ig {

using base::InputError;

}  // namespace ig
