#pragma once
// Normals: PCA over each point's neighbourhood, flipped towards the sensor. An organized scene
// computes them only where SHOT will read them (around its keypoints); an unorganized one needs
// every normal for the boundary test.
#include <cstdint>
#include <memory>
#include <vector>

#include "core/common/types.h"
#include "core/frontend/params.h"

namespace ism {

class NeighbourGrid;

// PCA normals over params.radius, flipped towards `viewpoint`, computed for the points asked
// for. SHOT reads the normals of the points within its radius of a keypoint only: on the Kinect
// frames that is 9-28% of the points, so an organized scene, whose keypoints are known before its
// normals, computes no others. A normal is undefined (and its point not part of the surface) with
// fewer than 3 neighbours. `cloud` must outlive the estimator.
class NormalEstimator {
 public:
  NormalEstimator(const XyzCloud& cloud, const NormalParams& params, const Eigen::Vector3f& viewpoint);
  ~NormalEstimator();

  void computeAll();
  // The normals of the points with wanted[i] != 0 (one flag per cloud point) not computed yet.
  void compute(const std::vector<uint8_t>& wanted);
  // The normals of every point within `radius` of one of cloud[centres].
  void computeNear(const std::vector<int>& centres, float radius);

  const XyzCloud& cloud() const { return cloud_; }
  // defined()[i]: point i's normal has been computed and is defined.
  const std::vector<uint8_t>& defined() const { return defined_; }
  // The nearest point with a defined normal within `max_distance` of `query`, or -1; only points
  // whose normals have been computed count.
  int nearestDefined(const Eigen::Vector3f& query, float max_distance) const;
  // The flags of the points within `radius` of one of `queries`.
  std::vector<uint8_t> pointsNear(const std::vector<Eigen::Vector3f>& queries, float radius) const;
  // The points with a defined normal, in cloud order. index_in_surface (when not null) receives,
  // per cloud point, its index in the surface or -1.
  Surface::Ptr surface(std::vector<int>* index_in_surface = nullptr) const;

 private:
  const XyzCloud& cloud_;
  NormalParams params_;
  Eigen::Vector3f viewpoint_;
  std::unique_ptr<NeighbourGrid> grid_;  // cells of the normals' radius
  std::vector<pcl::PointNormal> normals_;
  std::vector<uint8_t> computed_, defined_;
};

// Every point's normal (NormalEstimator::computeAll): the surface of the boundary test.
Surface::Ptr estimateNormals(const XyzCloud& cloud, const NormalParams& params,
                             const Eigen::Vector3f& viewpoint);

}  // namespace ism
