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

// A verified hypothesis whose box of `size` stands on z = 0 at (x, y).
inline Hypothesis verifiedStandingAt(const std::string& category, const Eigen::Vector3f& size, float x, float y) {
  UprightBox box;
  box.size = size;
  box.center = {x, y, size.z() / 2};
  return verifiedHypothesis(category, box);
}

// A verified couch 2 x 0.9 x 0.85 m standing on z = 0 at (0, y).
inline Hypothesis verifiedCouchAt(float y) { return verifiedStandingAt("couch", {2.0f, 0.9f, 0.85f}, 0.0f, y); }

}  // namespace ism::testing
