#pragma once
// The front end's parameter checks: an invalid value is refused with a message that names the
// parameter as the model file and the tools spell it (e.g. "downsample.leaf_size").
#include <cmath>
#include <string>

#include "core/common/error.h"

namespace ism {

inline void requirePositive(float value, const char* name) {
  if (!(std::isfinite(value) && value > 0.0f)) {
    throw Error(ErrorCode::kInvalidInput, std::string("front end parameter ") + name + " = " +
                                              std::to_string(value) + " must be positive and finite");
  }
}

inline void requireAtLeast(int value, int minimum, const char* name) {
  if (value < minimum) {
    throw Error(ErrorCode::kInvalidInput, std::string("front end parameter ") + name + " = " + std::to_string(value) +
                                              " must be >= " + std::to_string(minimum));
  }
}

}  // namespace ism
