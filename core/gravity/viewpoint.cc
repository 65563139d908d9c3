#include "core/gravity/viewpoint.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace ism {

namespace {

// The decisions below look at this many points of a cloud at most: every point of a big one
// would cost more than the rest of the decision needs.
size_t sampleStride(size_t points) { return std::max<size_t>(1, points / 20000); }

// An unorganized cloud without a sensor pose (origin at zero, identity orientation).
bool poseless(const Scene& scene) {
  return scene.cloud && !scene.cloud->empty() && scene.image_width == 0 && scene.sensor_origin.isZero() &&
         scene.sensor_orientation.isApprox(Eigen::Quaternionf::Identity());
}

// How a poseless cloud lies about its origin: a map when its points surround it, else a single
// view along its line of sight (the points' mean direction; none when no point is off the origin).
struct Spread {
  bool map = false;
  std::optional<Eigen::Vector3f> line_of_sight;
};

Spread spreadAbout(const Cloud& cloud, const Eigen::Vector3f& viewpoint, const ViewpointParams& params) {
  const auto& points = cloud.points;
  const size_t stride = sampleStride(points.size());
  const Eigen::Vector3d origin = viewpoint.cast<double>();
  Eigen::Vector3d mean_direction = Eigen::Vector3d::Zero();
  size_t counted = 0;
  for (size_t i = 0; i < points.size(); i += stride) {
    const Eigen::Vector3d p = points[i].getVector3fMap().cast<double>() - origin;
    if (p.norm() > 1e-6) mean_direction += p.normalized(), ++counted;
  }
  if (counted == 0) return {};
  if (!(mean_direction.norm() > 1e-9)) return {true, std::nullopt};
  mean_direction.normalize();
  const double cos_limit = std::cos(params.max_view_angle_deg * M_PI / 180.0);
  size_t outside = 0;
  for (size_t i = 0; i < points.size(); i += stride) {
    const Eigen::Vector3d p = points[i].getVector3fMap().cast<double>() - origin;
    if (p.norm() > 1e-6 && p.normalized().dot(mean_direction) < cos_limit) ++outside;
  }
  if (static_cast<double>(outside) > params.outside_fraction * static_cast<double>(counted)) return {true, std::nullopt};
  return {false, mean_direction.cast<float>()};
}

MapView mapView(const Scene& scene, const ViewpointParams& params) {
  const Eigen::Vector3f up = scene.up ? scene.up->normalized() : mapUp(*scene.cloud);
  return MapView{roomCentreViewpoint(*scene.cloud, up, params.eye_height), up};
}

// The sensor orientation whose up, the optical frame's -y, is `up`.
Eigen::Quaternionf orientationWithUp(const Eigen::Vector3f& up) {
  return Eigen::Quaternionf::FromTwoVectors(Eigen::Vector3f(0, -1, 0), up);
}

}  // namespace

std::optional<MapView> mapViewpoint(const Scene& scene, const ViewpointParams& params) {
  if (!poseless(scene) || !spreadAbout(*scene.cloud, Eigen::Vector3f::Zero(), params).map) return std::nullopt;
  return mapView(scene, params);
}

bool surrounds(const Cloud& cloud, const Eigen::Vector3f& viewpoint, const ViewpointParams& params) {
  return !cloud.empty() && spreadAbout(cloud, viewpoint, params).map;
}

bool isMap(const Scene& scene, const ViewpointParams& params) {
  return scene.cloud && scene.image_width == 0 && surrounds(*scene.cloud, scene.sensor_origin, params);
}

bool facesItsPoints(const Scene& scene) {
  if (!scene.cloud || scene.cloud->empty()) return true;
  const Eigen::Matrix3f to_sensor = scene.sensor_orientation.normalized().toRotationMatrix().transpose();
  const auto& points = scene.cloud->points;
  const size_t stride = sampleStride(points.size());
  size_t in_front = 0, counted = 0;
  for (size_t i = 0; i < points.size(); i += stride, ++counted) {
    if ((to_sensor * (points[i].getVector3fMap() - scene.sensor_origin)).z() > 0) ++in_front;
  }
  return 2 * in_front >= counted;
}

Scene lookedAt(const Scene& scene, const ViewpointParams& params) {
  Scene seen = scene;
  if (scene.image_width > 0 && !facesItsPoints(scene)) seen.sensor_orientation = Eigen::Quaternionf::Identity();
  if (!poseless(scene)) return seen;
  const Spread spread = spreadAbout(*scene.cloud, Eigen::Vector3f::Zero(), params);
  if (spread.map) {
    const MapView view = mapView(scene, params);
    seen.sensor_origin = view.origin;
    if (!scene.up) seen.sensor_orientation = orientationWithUp(view.up);
  } else if (!scene.up) {
    // A single view without pose, grid or up: written z up (SUN RGB-D's frames, a robot's base
    // frame) as often as in the camera's optical frame (-y up). Its floor is sought along the axis
    // a map's would be, of those across its line of sight.
    seen.sensor_orientation = orientationWithUp(mapUp(*scene.cloud, spread.line_of_sight));
  }
  return seen;
}

Eigen::Vector3f mapUp(const Cloud& cloud, const std::optional<Eigen::Vector3f>& looking) {
  const size_t stride = sampleStride(cloud.size());
  Eigen::Vector3f best = Eigen::Vector3f::UnitZ();
  size_t most = 0;
  bool any = false;
  for (const Eigen::Vector3f& axis : {Eigen::Vector3f(0, 0, 1), Eigen::Vector3f(0, -1, 0), Eigen::Vector3f(0, 1, 0)}) {
    // A view's far wall faces it: a dense layer across its line of sight, never its floor.
    if (looking && std::abs(axis.dot(*looking)) > std::cos(static_cast<float>(M_PI) / 4)) continue;
    if (!any) best = axis, any = true;
    std::vector<float> heights;
    for (size_t i = 0; i < cloud.size(); i += stride) heights.push_back(axis.dot(cloud[i].getVector3fMap()));
    const auto low = heights.begin() + static_cast<long>(heights.size() / 100);
    std::nth_element(heights.begin(), low, heights.end());
    const float floor = *low;
    constexpr float kLayer = 0.05f;
    const auto layer = static_cast<size_t>(
        std::count_if(heights.begin(), heights.end(), [&](float h) { return std::abs(h - floor) <= kLayer; }));
    if (layer > most) most = layer, best = axis;  // ties keep the earlier axis
  }
  return best;
}

Eigen::Vector3f roomCentreViewpoint(const Cloud& cloud, const Eigen::Vector3f& up_direction, float eye_height) {
  const Eigen::Vector3f up = up_direction.normalized();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::vector<float> heights;
  heights.reserve(cloud.size());
  for (const auto& p : cloud) {
    sum += p.getVector3fMap().cast<double>();
    heights.push_back(up.dot(p.getVector3fMap()));
  }
  const auto floor = heights.begin() + static_cast<long>(heights.size() / 100);
  std::nth_element(heights.begin(), floor, heights.end());
  const Eigen::Vector3f centroid = (sum / static_cast<double>(cloud.size())).cast<float>();
  return centroid - up * up.dot(centroid) + up * (*floor + eye_height);
}

}  // namespace ism
