#include "core/frontend/upright_geometry.h"

#include "core/common/error.h"
#include "core/frontend/neighbour_grid.h"

namespace ism {

void addUprightGeometry(const Surface& surface, const std::vector<int>& described, const Gravity& gravity,
                        float radius, Features& features) {
  if (described.size() != features.size()) {
    throw Error(ErrorCode::kInternal, "addUprightGeometry: " + std::to_string(described.size()) +
                                          " described keypoints for " + std::to_string(features.size()) + " features");
  }
  features.gravity = gravity;
  features.heights.clear();
  features.normals.clear();
  features.support_directions.clear();
  if (gravity.hasFloor()) {
    for (const auto& p : features.positions) features.heights.push_back(gravity.height(p));
  }
  features.normals.reserve(features.size());
  features.support_directions.reserve(features.size());
  const NeighbourGrid grid(surface, radius);
  std::vector<int> neighbours;
  std::vector<float> squared;
  for (size_t i = 0; i < features.size(); ++i) {
    const pcl::PointNormal& keypoint = surface[static_cast<size_t>(described[i])];
    features.normals.push_back(keypoint.getNormalVector3fMap());
    grid.radiusSearch(features.positions[i], radius, neighbours, squared);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int n : neighbours) sum += surface[static_cast<size_t>(n)].getVector3fMap().cast<double>();
    // The keypoint itself is among its neighbours, so there is at least one.
    const Eigen::Vector3f centroid = (sum / static_cast<double>(std::max<size_t>(1, neighbours.size()))).cast<float>();
    features.support_directions.push_back(centroid - features.positions[i]);
  }
}

}  // namespace ism
