#include "core/frontend/keypoints.h"

#include <pcl/features/boundary.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "core/common/error.h"
#include "core/frontend/neighbour_grid.h"
#include "core/frontend/occluding_contours.h"
#include "core/frontend/range_image.h"
#include "core/frontend/param_checks.h"

namespace ism {
namespace {

// A cell of the grid of cubes of edge 1 / inverse_size with a corner at the origin.
struct Cell {
  int64_t x, y, z;
  bool operator==(const Cell& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct CellHash {
  size_t operator()(const Cell& c) const {
    return static_cast<size_t>(c.x * 73856093) ^ static_cast<size_t>(c.y * 19349663) ^
           static_cast<size_t>(c.z * 83492791);
  }
};
template <class Point>
Cell cellOf(const Point& p, float inverse_size) {
  return {static_cast<int64_t>(std::floor(p.x * inverse_size)), static_cast<int64_t>(std::floor(p.y * inverse_size)),
          static_cast<int64_t>(std::floor(p.z * inverse_size))};
}

// Ascending and unique: nearest(q) for each of `queries`, those not -1 (indices below `points`).
template <class Nearest>
std::vector<int> nearestOfEach(const std::vector<Eigen::Vector3f>& queries, size_t points, Nearest&& nearest) {
  std::vector<int> nearest_of(queries.size(), -1);
#pragma omp parallel for schedule(dynamic, 256)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(queries.size()); ++i) {
    nearest_of[static_cast<size_t>(i)] = nearest(queries[static_cast<size_t>(i)]);
  }
  std::vector<uint8_t> selected(points, 0);
  for (int n : nearest_of) {
    if (n >= 0) selected[static_cast<size_t>(n)] = 1;
  }
  std::vector<int> indices;
  for (size_t i = 0; i < points; ++i) {
    if (selected[i]) indices.push_back(static_cast<int>(i));
  }
  return indices;
}

}  // namespace

std::vector<int> detectBoundaryKeypoints(const Surface& surface, const KeypointParams& params) {
  requirePositive(params.radius, "keypoints.radius");
  requirePositive(params.angle_threshold, "keypoints.angle_threshold");
  std::vector<int> keypoints;
  if (surface.empty()) return keypoints;
  // pcl::BoundaryEstimation has no parallel variant; its per-point test is public and reads
  // only its arguments, so the same test runs here over all cores.
  pcl::BoundaryEstimation<pcl::PointNormal, pcl::PointNormal, pcl::Boundary> estimator;
  std::vector<uint8_t> is_boundary(surface.size(), 0);
  NeighbourGrid(surface, params.radius).forEachPoint(params.radius, [&](int i, const std::vector<int>& neighbours) {
    Eigen::Vector4f u, v;
    estimator.getCoordinateSystemOnPlane(surface[static_cast<size_t>(i)], u, v);
    is_boundary[static_cast<size_t>(i)] = estimator.isBoundaryPoint(surface, i, neighbours, u, v, params.angle_threshold);
  });
  for (size_t i = 0; i < surface.size(); ++i) {
    if (is_boundary[i]) keypoints.push_back(static_cast<int>(i));
  }
  return keypoints;
}

KeypointMethod resolveKeypointMethod(const KeypointParams& params, const Scene& scene) {
  if (params.method != KeypointMethod::kAuto) return params.method;
  return scene.pixel_index.empty() ? params.unorganized : KeypointMethod::kOccludingContour;
}

std::vector<int> nearestSurfacePoints(const Surface& surface, const Cloud& cloud, const std::vector<int>& point_indices,
                                      float max_distance) {
  requirePositive(max_distance, "nearestSurfacePoints max_distance");
  std::vector<Eigen::Vector3f> queries;
  queries.reserve(point_indices.size());
  for (int i : point_indices) {
    if (i < 0 || static_cast<size_t>(i) >= cloud.size()) {
      throw Error(ErrorCode::kInvalidInput, "edge point index " + std::to_string(i) + " is outside the cloud of " +
                                                std::to_string(cloud.size()) + " points");
    }
    queries.push_back(cloud[static_cast<size_t>(i)].getVector3fMap());
  }
  if (surface.empty() || queries.empty()) return {};
  const NeighbourGrid grid(surface, max_distance);
  return nearestOfEach(queries, surface.size(), [&](const Eigen::Vector3f& q) { return grid.nearest(q, max_distance); });
}

template <class PointT>
std::vector<int> thinKeypoints(const pcl::PointCloud<PointT>& points, const std::vector<int>& keypoints, float spacing) {
  if (spacing == 0.0f) return keypoints;
  requirePositive(spacing, "keypoints.min_spacing");
  const float inverse_spacing = 1.0f / spacing;
  std::unordered_set<Cell, CellHash> taken;
  std::vector<int> kept;
  for (int k : keypoints) {
    if (taken.insert(cellOf(points.at(static_cast<size_t>(k)), inverse_spacing)).second) kept.push_back(k);
  }
  return kept;
}
template std::vector<int> thinKeypoints(const Surface&, const std::vector<int>&, float);
template std::vector<int> thinKeypoints(const XyzCloud&, const std::vector<int>&, float);

std::vector<int> detectKeypoints(const Scene& scene, const Surface& surface, const KeypointParams& params,
                                 float leaf_size) {
  std::vector<int> keypoints;
  const KeypointMethod method = resolveKeypointMethod(params, scene);
  if (method == KeypointMethod::kBoundary) {
    keypoints = detectBoundaryKeypoints(surface, params);
  } else if (method == KeypointMethod::kRangeImage) {
    XyzCloud points;
    for (const auto& p : surface) points.push_back({p.x, p.y, p.z});
    const Scene view = rangeImageView(points, scene.sensor_origin,
                                      scene.up.value_or(scene.sensor_orientation * Eigen::Vector3f(0, -1, 0)),
                                      params.range_image);
    if (view.image_width > 0) {
      keypoints = nearestSurfacePoints(surface, *view.cloud, detectOccludingContourPixels(view, params.contour), leaf_size);
    }
  } else {
    keypoints = nearestSurfacePoints(surface, *scene.cloud, detectOccludingContourPixels(scene, params.contour),
                                     leaf_size);
  }
  return thinKeypoints(surface, keypoints, params.min_spacing);
}

std::vector<int> sampleSurfaceKeypoints(const XyzCloud& points, const std::vector<uint8_t>& eligible,
                                        const SurfaceSampling& sampling) {
  requirePositive(sampling.spacing, "keypoints.surface_spacing");
  if (eligible.size() != points.size()) {
    throw Error(ErrorCode::kInternal, "sampleSurfaceKeypoints: " + std::to_string(eligible.size()) + " flags for " +
                                          std::to_string(points.size()) + " points");
  }
  const float inverse_spacing = 1.0f / sampling.spacing;
  struct Cube {
    int nearest = -1;  // the eligible point nearest the centre
    float squared_distance = 0;
    int points = 0;  // eligible ones
  };
  std::unordered_map<Cell, Cube, CellHash> cubes;
  for (size_t i = 0; i < points.size(); ++i) {
    if (!eligible[i]) continue;
    const Cell cell = cellOf(points[i], inverse_spacing);
    const Eigen::Vector3f centre =
        (Eigen::Vector3f(static_cast<float>(cell.x), static_cast<float>(cell.y), static_cast<float>(cell.z)) +
         Eigen::Vector3f::Constant(0.5f)) * sampling.spacing;
    const float d = (points[i].getVector3fMap() - centre).squaredNorm();
    Cube& cube = cubes[cell];
    ++cube.points;
    if (cube.nearest < 0 || d < cube.squared_distance) cube.nearest = static_cast<int>(i), cube.squared_distance = d;
  }
  std::vector<int> sampled;
  for (const auto& [cell, cube] : cubes) {
    if (cube.points >= sampling.min_points) sampled.push_back(cube.nearest);
  }
  std::sort(sampled.begin(), sampled.end());
  if (sampling.clearance > 0 && std::find(eligible.begin(), eligible.end(), 0) != eligible.end()) {
    std::vector<uint8_t> others(eligible.size());
    for (size_t i = 0; i < eligible.size(); ++i) others[i] = !eligible[i];
    const NeighbourGrid grid(points, sampling.clearance);
    sampled.erase(std::remove_if(sampled.begin(), sampled.end(),
                                 [&](int i) {
                                   return grid.nearest(points[static_cast<size_t>(i)].getVector3fMap(),
                                                       sampling.clearance, &others) >= 0;
                                 }),
                  sampled.end());
  }
  return sampled;
}

std::vector<int> detectContourKeypoints(const Scene& scene, NormalEstimator& normals, const KeypointParams& params,
                                        float leaf_size) {
  requirePositive(leaf_size, "nearestSurfacePoints max_distance");
  const std::vector<int> pixels = detectOccludingContourPixels(scene, params.contour);
  std::vector<Eigen::Vector3f> edges;
  edges.reserve(pixels.size());
  for (int i : pixels) edges.push_back((*scene.cloud)[static_cast<size_t>(i)].getVector3fMap());
  // Only a point with a normal can be picked: first the normals of every point in reach.
  normals.compute(normals.pointsNear(edges, leaf_size));
  const std::vector<int> picked = nearestOfEach(
      edges, normals.cloud().size(), [&](const Eigen::Vector3f& q) { return normals.nearestDefined(q, leaf_size); });
  return thinKeypoints(normals.cloud(), picked, params.min_spacing);
}

}  // namespace ism
