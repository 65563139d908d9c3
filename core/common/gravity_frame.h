#pragma once
// Where up is in a scene and where its floor lies: what the gravity stage (core/gravity) finds
// and what every later stage reads (keypoint heights, upright vote frames, upright boxes).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <optional>

namespace ism {

// A rotation from scene coordinates into a frame whose z axis is `up` (unit length). The x axis is
// the scene's x (or y, when x is nearly vertical) made horizontal, so that the frame is the same
// for every call with the same up.
Eigen::Matrix3f gravityRotation(const Eigen::Vector3f& up);

enum class UpSource {
  kGiven,    // the caller's
  kFloor,    // the normal of the floor found in the scene
  kAssumed,  // no floor found: the sensor's up (the optical frame's -y), unchecked
};
const char* toString(UpSource source);

struct Gravity {
  Eigen::Vector3f up = Eigen::Vector3f::UnitZ();  // unit, scene coordinates
  UpSource source = UpSource::kAssumed;
  // The floor plane is { p : up . p = floor_level } when found.
  std::optional<float> floor_level;
  size_t floor_points = 0;  // points on the floor plane
  size_t wall_points = 0;   // points on walls
  int walls = 0;

  bool hasFloor() const { return floor_level.has_value(); }
  // Height of p above the floor; only meaningful when hasFloor().
  float height(const Eigen::Vector3f& p) const { return up.dot(p) - floor_level.value_or(0.0f); }
  // Scene -> a frame whose z is up.
  Eigen::Matrix3f toGravity() const { return gravityRotation(up); }
};

}  // namespace ism
