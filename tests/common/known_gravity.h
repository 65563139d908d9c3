#pragma once
// The gravity of the scenes the tests render (composeScene): z up, the floor at z = 0, given
// rather than found, so a test of a later stage does not depend on the floor search.
#include <Eigen/Core>

#include "core/common/gravity_frame.h"

namespace ism::testing {

inline Gravity knownFloor() {
  Gravity g;
  g.up = Eigen::Vector3f::UnitZ();
  g.source = UpSource::kGiven;
  g.floor_level = 0.0f;
  return g;
}

}  // namespace ism::testing
