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

// A verified couch 2 x 0.9 x 0.85 m standing on z = 0 at (0, y).
inline Hypothesis verifiedCouchAt(float y) {
  UprightBox box;
  box.size = {2.0f, 0.9f, 0.85f};
  box.center = {0.0f, y, 0.425f};
  return verifiedHypothesis("couch", box);
}

}  // namespace ism::testing
