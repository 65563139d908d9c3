#include "core/frontend/range_image.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <pcl/kdtree/kdtree_flann.h>

#include "core/common/gravity_frame.h"

namespace ism {
namespace {

// Median over a sample of points of (distance to the nearest neighbour) / (range): the angle
// between neighbouring points as the sensor sees them.
float medianNeighbourAngle(const XyzCloud& points, const Eigen::Vector3f& origin) {
  const XyzCloud::ConstPtr cloud(new XyzCloud(points));
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(cloud);
  const size_t samples = std::min<size_t>(points.size(), 2000);
  const size_t stride = points.size() / samples;
  std::vector<float> angles;
  std::vector<int> index(2);
  std::vector<float> squared(2);
  for (size_t i = 0; i < points.size() && angles.size() < samples; i += stride) {
    const float range = (points[i].getVector3fMap() - origin).norm();
    if (range <= 0 || tree.nearestKSearch(points[i], 2, index, squared) < 2) continue;
    angles.push_back(std::sqrt(squared[1]) / range);
  }
  if (angles.empty()) return 0;
  std::nth_element(angles.begin(), angles.begin() + static_cast<long>(angles.size() / 2), angles.end());
  return angles[angles.size() / 2];
}

float wrapAngle(float a) {
  constexpr float kPi = static_cast<float>(M_PI);
  while (a > kPi) a -= 2 * kPi;
  while (a <= -kPi) a += 2 * kPi;
  return a;
}

}  // namespace

Scene rangeImageView(const XyzCloud& points, const Eigen::Vector3f& origin, const Eigen::Vector3f& up,
                     const RangeImageParams& params) {
  Scene view;
  view.sensor_origin = origin;
  if (points.size() < 2) return view;
  const Eigen::Matrix3f to_up = gravityRotation(up);
  std::vector<float> azimuth(points.size()), elevation(points.size()), range(points.size());
  Eigen::Vector2f heading = Eigen::Vector2f::Zero();
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f v = to_up * (points[i].getVector3fMap() - origin);
    range[i] = v.norm();
    if (!(range[i] > 0)) continue;
    azimuth[i] = std::atan2(v.y(), v.x());
    elevation[i] = std::asin(std::clamp(v.z() / range[i], -1.0f, 1.0f));
    if (v.head<2>().norm() > 0) heading += v.head<2>().normalized();
  }
  const float forward = heading.norm() > 0 ? std::atan2(heading.y(), heading.x()) : 0.0f;
  float az_lo = std::numeric_limits<float>::max(), az_hi = -az_lo, el_lo = az_lo, el_hi = -az_lo;
  for (size_t i = 0; i < points.size(); ++i) {
    if (!(range[i] > 0)) continue;
    azimuth[i] = wrapAngle(azimuth[i] - forward);
    az_lo = std::min(az_lo, azimuth[i]);
    az_hi = std::max(az_hi, azimuth[i]);
    el_lo = std::min(el_lo, elevation[i]);
    el_hi = std::max(el_hi, elevation[i]);
  }
  float pixel = params.pixel_spacings * medianNeighbourAngle(points, origin);
  if (!(pixel > 0) || az_lo > az_hi) return view;
  // Capped in size: a few far-off points of a dense cloud would otherwise ask for a huge image.
  const auto columns = [&] { return static_cast<long>((az_hi - az_lo) / pixel) + 1; };
  const auto rows = [&] { return static_cast<long>((el_hi - el_lo) / pixel) + 1; };
  while (columns() * rows() > params.max_pixels) pixel *= 1.25f;
  const long width = columns(), height = rows();
  if (width < 3 || height < 3) return view;
  std::vector<int> nearest(static_cast<size_t>(width * height), -1);
  for (size_t i = 0; i < points.size(); ++i) {
    if (!(range[i] > 0)) continue;
    const long col = std::min(width - 1, static_cast<long>((azimuth[i] - az_lo) / pixel));
    const long row = std::min(height - 1, static_cast<long>((el_hi - elevation[i]) / pixel));
    int& best = nearest[static_cast<size_t>(row * width + col)];
    if (best < 0 || range[i] < range[static_cast<size_t>(best)]) best = static_cast<int>(i);
  }
  view.image_width = static_cast<int>(width);
  view.image_height = static_cast<int>(height);
  for (size_t p = 0; p < nearest.size(); ++p) {
    if (nearest[p] < 0) continue;
    PointT point;
    point.getVector3fMap() = points[static_cast<size_t>(nearest[p])].getVector3fMap();
    view.cloud->push_back(point);
    view.pixel_index.push_back(static_cast<int>(p));
  }
  return view;
}

}  // namespace ism
