#pragma once
// Where a cloud was seen from. Normals face the sensor, the range-image keypoints are contours
// seen from it and verification asks what it should have seen, so every unorganized cloud needs
// a viewpoint. A depth frame has one (its camera, the frame's origin, or the pose the file or the
// request gives). A fused map (a robot's mapping stack, a ScanNet room) has none: its points
// surround whatever its frame's origin is, often a spot on the floor. Such a cloud is looked at
// from the middle of its points at eye height above its lowest points, as the evaluation of fused
// rooms does (docs/EVALUATION.md; VoteNet's ScanNet clouds come without any camera either).
#include <Eigen/Core>
#include <optional>

#include "core/common/types.h"

namespace ism {

struct ViewpointParams {
  // A single view's points lie within a cone about its mean direction: a Kinect's field of view
  // is 57 x 43 degrees (35 degrees to a corner), the widest depth cameras' about 120 degrees.
  // More than `outside_fraction` of the points farther than `max_view_angle_deg` from the mean
  // direction, and the cloud was not seen from its origin.
  float max_view_angle_deg = 65.0f;
  float outside_fraction = 0.05f;
  // The viewpoint of a map: this high above its 1st percentile along up (m).
  float eye_height = 1.5f;
};

// The viewpoint for `scene` when it is a map seen from nowhere: an unorganized cloud without a
// sensor pose (origin at zero, identity orientation) whose points are not a single view from the
// origin. Up is the caller's (scene.up) or else the sensor's (-y). Nothing for every other scene,
// whose own sensor origin stands.
std::optional<Eigen::Vector3f> mapViewpoint(const Scene& scene, const ViewpointParams& params = {});

// The middle of a room: the points' centroid across `up`, `eye_height` above their 1st percentile
// along it (a low percentile rather than the minimum: reconstructions have stray points below the
// floor). `cloud` must not be empty.
Eigen::Vector3f roomCentreViewpoint(const Cloud& cloud, const Eigen::Vector3f& up, float eye_height);

}  // namespace ism
