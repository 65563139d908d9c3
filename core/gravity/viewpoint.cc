#include "core/gravity/viewpoint.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace ism {

std::optional<Eigen::Vector3f> mapViewpoint(const Scene& scene, const ViewpointParams& params) {
  if (!scene.cloud || scene.cloud->empty() || scene.image_width > 0) return std::nullopt;
  if (!scene.sensor_origin.isZero() || !scene.sensor_orientation.isApprox(Eigen::Quaternionf::Identity())) {
    return std::nullopt;
  }
  const auto& points = scene.cloud->points;
  // Every point counted on big clouds would cost more than the rest of the decision needs.
  const size_t stride = std::max<size_t>(1, points.size() / 20000);
  Eigen::Vector3d mean_direction = Eigen::Vector3d::Zero();
  size_t counted = 0;
  for (size_t i = 0; i < points.size(); i += stride) {
    const Eigen::Vector3d p = points[i].getVector3fMap().cast<double>();
    if (p.norm() > 1e-6) mean_direction += p.normalized(), ++counted;
  }
  if (counted == 0) return std::nullopt;
  bool single_view = mean_direction.norm() > 1e-9;
  if (single_view) {
    mean_direction.normalize();
    const double cos_limit = std::cos(params.max_view_angle_deg * M_PI / 180.0);
    size_t outside = 0;
    for (size_t i = 0; i < points.size(); i += stride) {
      const Eigen::Vector3d p = points[i].getVector3fMap().cast<double>();
      if (p.norm() > 1e-6 && p.normalized().dot(mean_direction) < cos_limit) ++outside;
    }
    single_view = static_cast<double>(outside) <= params.outside_fraction * static_cast<double>(counted);
  }
  if (single_view) return std::nullopt;
  return roomCentreViewpoint(*scene.cloud, scene.up ? *scene.up : Eigen::Vector3f(0, -1, 0), params.eye_height);
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
