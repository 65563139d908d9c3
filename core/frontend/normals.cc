#include "core/frontend/normals.h"

#include <pcl/features/normal_3d.h>

#include <limits>
#include <string>

#include "core/common/error.h"
#include "core/frontend/neighbour_grid.h"
#include "core/frontend/param_checks.h"

namespace ism {
namespace {


// pcl::computePointNormal(cloud, neighbour indices, ...) (PCL 1.13 features/normal_3d.h) over
// the neighbourhood the grid found, with the coordinates read from the grid's arrays, where the
// neighbours lie together, rather than through an index list into the cloud. The mean and
// covariance repeat pcl::computeMeanAndCovarianceMatrix (common/impl/centroid.hpp) float
// operation for float operation, in its order, on the same values, so the normals are
// bit-identical to PCL's (frontend_test, Normals.NearTheCentres...); the plane and curvature
// then come from PCL's own solvePlaneParameters. Keep the two in step when PCL changes. (A
// build for a target with FMA could fuse the products into the sums differently from PCL's
// copy; the test would tell.)
bool pointNormal(const NeighbourGrid::Neighbourhood& neighbours, Eigen::Vector4f& plane, float& curvature) {
  const size_t n = neighbours.size();
  if (n < 3) {
    plane.setConstant(std::numeric_limits<float>::quiet_NaN());
    curvature = std::numeric_limits<float>::quiet_NaN();
    return false;
  }
  // PCL shifts by the first finite neighbour and skips the others that are not (unless the cloud
  // says it is dense). Every neighbour is finite: a point with a NaN or infinite coordinate is
  // at a NaN or infinite distance, never within the radius.
  const float kx = neighbours.x(0), ky = neighbours.y(0), kz = neighbours.z(0);
  Eigen::Matrix<float, 1, 9, Eigen::RowMajor> accu = Eigen::Matrix<float, 1, 9, Eigen::RowMajor>::Zero();
  for (size_t k = 0; k < n; ++k) {
    const float x = neighbours.x(k) - kx, y = neighbours.y(k) - ky, z = neighbours.z(k) - kz;
    accu[0] += x * x;
    accu[1] += x * y;
    accu[2] += x * z;
    accu[3] += y * y;
    accu[4] += y * z;
    accu[5] += z * z;
    accu[6] += x;
    accu[7] += y;
    accu[8] += z;
  }
  accu /= static_cast<float>(n);
  Eigen::Vector4f centroid;
  centroid[0] = accu[6] + kx;
  centroid[1] = accu[7] + ky;
  centroid[2] = accu[8] + kz;
  centroid[3] = 1;
  EIGEN_ALIGN16 Eigen::Matrix3f covariance;
  covariance.coeffRef(0) = accu[0] - accu[6] * accu[6];
  covariance.coeffRef(1) = accu[1] - accu[6] * accu[7];
  covariance.coeffRef(2) = accu[2] - accu[6] * accu[8];
  covariance.coeffRef(4) = accu[3] - accu[7] * accu[7];
  covariance.coeffRef(5) = accu[4] - accu[7] * accu[8];
  covariance.coeffRef(8) = accu[5] - accu[8] * accu[8];
  covariance.coeffRef(3) = covariance.coeff(1);
  covariance.coeffRef(6) = covariance.coeff(2);
  covariance.coeffRef(7) = covariance.coeff(5);
  pcl::solvePlaneParameters(covariance, centroid, plane, curvature);
  return true;
}

}  // namespace

NormalEstimator::NormalEstimator(const XyzCloud& cloud, const NormalParams& params, const Eigen::Vector3f& viewpoint)
    : cloud_(cloud), params_(params), viewpoint_(viewpoint) {
  requirePositive(params.radius, "normals.radius");
  grid_ = std::make_unique<NeighbourGrid>(cloud, params.radius);
  normals_.resize(cloud.size());
  computed_.assign(cloud.size(), 0);
  defined_.assign(cloud.size(), 0);
}

NormalEstimator::~NormalEstimator() = default;

void NormalEstimator::computeAll() { compute(std::vector<uint8_t>(cloud_.size(), 1)); }

void NormalEstimator::compute(const std::vector<uint8_t>& wanted) {
  if (wanted.size() != cloud_.size()) {
    throw Error(ErrorCode::kInternal, "NormalEstimator::compute: " + std::to_string(wanted.size()) + " flags for " +
                                          std::to_string(cloud_.size()) + " points");
  }
  std::vector<uint8_t> todo(wanted.size());
  for (size_t i = 0; i < wanted.size(); ++i) todo[i] = wanted[i] && !computed_[i];
  grid_->forEachNeighbourhood(params_.radius, [&](int i, const NeighbourGrid::Neighbourhood& neighbours) {
    const auto at = static_cast<size_t>(i);
    computed_[at] = 1;
    // The same PCA as pcl::NormalEstimation: undefined (NaN) below 3 neighbours.
    Eigen::Vector4f plane;
    float curvature = 0.0f;
    if (!pointNormal(neighbours, plane, curvature) || !plane.head<3>().allFinite()) return;
    // The point's coordinates from the grid, next to its neighbours': the cloud itself is read
    // in the grid's order, all over its 1.3 MB, and its loads missed the cache.
    const Eigen::Vector3f point = neighbours.point();
    const pcl::PointXYZ q(point.x(), point.y(), point.z());
    pcl::flipNormalTowardsViewpoint(q, viewpoint_.x(), viewpoint_.y(), viewpoint_.z(), plane);
    pcl::PointNormal& p = normals_[at];
    p.x = q.x;
    p.y = q.y;
    p.z = q.z;
    p.normal_x = plane[0];
    p.normal_y = plane[1];
    p.normal_z = plane[2];
    p.curvature = curvature;
    defined_[at] = 1;
  }, &todo);
}

std::vector<uint8_t> NormalEstimator::pointsNear(const std::vector<Eigen::Vector3f>& queries, float radius) const {
  return grid_->pointsWithin(queries, radius);
}

void NormalEstimator::computeNear(const std::vector<int>& centres, float radius) {
  std::vector<Eigen::Vector3f> queries;
  queries.reserve(centres.size());
  for (int c : centres) queries.push_back(cloud_.at(static_cast<size_t>(c)).getVector3fMap());
  compute(pointsNear(queries, radius));
}

int NormalEstimator::nearestDefined(const Eigen::Vector3f& query, float max_distance) const {
  return grid_->nearest(query, max_distance, &defined_);
}

Surface::Ptr NormalEstimator::surface(std::vector<int>* index_in_surface) const {
  Surface::Ptr surface(new Surface);
  if (index_in_surface != nullptr) index_in_surface->assign(cloud_.size(), -1);
  for (size_t i = 0; i < cloud_.size(); ++i) {
    if (!defined_[i]) continue;
    if (index_in_surface != nullptr) (*index_in_surface)[i] = static_cast<int>(surface->size());
    surface->push_back(normals_[i]);
  }
  return surface;
}

Surface::Ptr estimateNormals(const XyzCloud& cloud, const NormalParams& params, const Eigen::Vector3f& viewpoint) {
  requirePositive(params.radius, "normals.radius");
  if (cloud.empty()) return Surface::Ptr(new Surface);
  NormalEstimator normals(cloud, params, viewpoint);
  normals.computeAll();
  return normals.surface();
}

}  // namespace ism
