#pragma once
// A hypothesis as verification leaves it: upright, verified, its box the fitted shape's.
#include <string>

#include <Eigen/Core>

#include "core/common/upright_box.h"
#include "core/recognition/hypothesis.h"

namespace ism::testing {

inline Hypothesis verifiedHypothesis(const std::string& category, const UprightBox& box) {
  Hypothesis h;
  h.category = category;
  h.box = box.toScene(Eigen::Matrix3f::Identity());
  h.upright_box = true;
  h.verification = Verification{};
  return h;
}

}  // namespace ism::testing
