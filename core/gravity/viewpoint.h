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

// How to look at a map seen from nowhere.
struct MapView {
  Eigen::Vector3f origin;  // the viewpoint
  Eigen::Vector3f up;      // the caller's, else mapUp()'s: where the gravity stage seeks the floor
};

// The view of `scene` when it is a map seen from nowhere: an unorganized cloud without a sensor
// pose (origin at zero, identity orientation) whose points are not a single view from the origin.
// Nothing for every other scene, whose own sensor stands.
std::optional<MapView> mapViewpoint(const Scene& scene, const ViewpointParams& params = {});

// Whether `cloud` surrounds `viewpoint`, a map's points do, rather than lying in one view from it:
// more than params.outside_fraction of them beyond max_view_angle_deg of their mean direction.
bool surrounds(const Cloud& cloud, const Eigen::Vector3f& viewpoint, const ViewpointParams& params = {});

// Whether `scene` is a map as recognition sees it (after lookedAt): an unorganized cloud whose
// points surround its sensor origin. Its viewpoint is made up, so what a sensor would have seen
// through is not known (frontend.h, verification.h).
bool isMap(const Scene& scene, const ViewpointParams& params = {});

// Whether at least half of the points lie in front of the sensor (+z of its optical frame, turned
// by its orientation). A depth image's points all do; some files' pose says otherwise (PCL's test
// frames such as office1.pcd carry a VIEWPOINT turned 180 degrees about x while their points are
// in the optical frame).
bool facesItsPoints(const Scene& scene);

// `scene` as recognition looks at it: a map seen from nowhere gets mapViewpoint()'s origin and,
// unless the caller gave up, a sensor orientation whose up (the optical frame's -y) is the map's
// likely up, which is where the gravity stage then seeks the floor. An image whose orientation
// turns its sensor away from its points (facesItsPoints) is taken in its points' own frame, the
// orientation dropped: its up would point down. A single view without image grid, pose or up
// gets the orientation whose up is mapUp()'s, as a map does. Other scenes are returned as they
// are. The copy shares the points.
Scene lookedAt(const Scene& scene, const ViewpointParams& params = {});

// A map's likely up when the caller does not say: of the axes maps are written with (+z of
// robots' maps, REP 103, and of ScanNet; -y of a camera's frame; +y of meshes), the one whose
// lowest layer of points (within 5 cm of the 1st percentile) holds the most of them: a floor,
// the largest surface of a room, rather than a wall. With `looking`, a single view's line of sight,
// the axes within 45 degrees of it are left out. `cloud` must not be empty.
Eigen::Vector3f mapUp(const Cloud& cloud, const std::optional<Eigen::Vector3f>& looking = std::nullopt);

// The middle of a room: the points' centroid across `up`, `eye_height` above their 1st percentile
// along it (a low percentile rather than the minimum: reconstructions have stray points below the
// floor). `cloud` must not be empty.
Eigen::Vector3f roomCentreViewpoint(const Cloud& cloud, const Eigen::Vector3f& up, float eye_height);

}  // namespace ism
