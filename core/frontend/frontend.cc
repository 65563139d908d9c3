#include "core/frontend/frontend.h"

#include <pcl/common/eigen.h>
#include <pcl/features/boundary.h>
#include <pcl/features/normal_3d.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <unordered_set>

#include "core/common/error.h"
#include "core/common/radix_sort.h"
#include "core/frontend/neighbour_grid.h"
#include "core/frontend/shot.h"

namespace ism {
namespace {

void requirePositive(float value, const char* name) {
  if (!(std::isfinite(value) && value > 0.0f)) {
    throw Error(ErrorCode::kInvalidInput, std::string("front end parameter ") + name + " = " +
                                              std::to_string(value) + " must be positive and finite");
  }
}

// Voxel centroids in pcl::VoxelGrid's output order (ascending linear voxel index: z, then y,
// then x). Written here rather than with pcl::VoxelGrid, which numbers voxels with a 32-bit index
// (silently returning its input when a room at a fine leaf overflows it) and sorts with std::sort;
// a 64-bit index and a radix sort take 0.4x its time on a Kinect frame. Non-finite points are
// skipped, as VoxelGrid does.
void voxelCentroids(const Cloud& cloud, float leaf, XyzCloud& out) {
  const float inverse_leaf = 1.0f / leaf;
  Eigen::Array3f lo = Eigen::Array3f::Constant(std::numeric_limits<float>::max());
  Eigen::Array3f hi = Eigen::Array3f::Constant(std::numeric_limits<float>::lowest());
  for (const auto& p : cloud) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    lo = lo.min(p.getArray3fMap());
    hi = hi.max(p.getArray3fMap());
  }
  if (!(lo <= hi).all()) return;  // no finite point
  Eigen::Array<int64_t, 3, 1> first, count;
  for (int axis = 0; axis < 3; ++axis) {
    const double low = std::floor(lo[axis] * inverse_leaf);  // in float, as each point is assigned below
    const double high = std::floor(hi[axis] * inverse_leaf);
    // Voxel numbers beyond this are no longer exact in the float arithmetic that assigns points.
    constexpr double kMaxVoxelCoordinate = std::numeric_limits<int>::max() / 2.0;
    if (std::abs(low) > kMaxVoxelCoordinate || std::abs(high) > kMaxVoxelCoordinate) {
      throw Error(ErrorCode::kInvalidInput,
                  "downsample.leaf_size = " + std::to_string(leaf) + " is too small for coordinates up to " +
                      std::to_string(std::max(std::abs(lo[axis]), std::abs(hi[axis]))) + " m");
    }
    first[axis] = static_cast<int64_t>(low);
    count[axis] = static_cast<int64_t>(high) - first[axis] + 1;
  }
  if (static_cast<double>(count[0]) * static_cast<double>(count[1]) * static_cast<double>(count[2]) >= 0x1p63) {
    throw Error(ErrorCode::kInvalidInput, "downsample.leaf_size = " + std::to_string(leaf) +
                                              " divides the cloud's extent into more than 2^63 voxels");
  }
  std::vector<std::pair<uint64_t, int>> keyed;
  keyed.reserve(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    const auto& p = cloud[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    const auto voxel = [&](float v, int axis) {
      return std::clamp<int64_t>(static_cast<int64_t>(std::floor(v * inverse_leaf)) - first[axis], 0, count[axis] - 1);
    };
    const uint64_t index = static_cast<uint64_t>((voxel(p.z, 2) * count[1] + voxel(p.y, 1)) * count[0] + voxel(p.x, 0));
    keyed.emplace_back(index, static_cast<int>(i));
  }
  sortByKey(keyed);
  for (size_t begin = 0; begin < keyed.size();) {
    size_t end = begin;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (; end < keyed.size() && keyed[end].first == keyed[begin].first; ++end) {
      sum += cloud[static_cast<size_t>(keyed[end].second)].getVector3fMap().cast<double>();
    }
    const Eigen::Vector3f centroid = (sum / static_cast<double>(end - begin)).cast<float>();
    out.push_back(pcl::PointXYZ(centroid.x(), centroid.y(), centroid.z()));
    begin = end;
  }
}

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

void requireAtLeast(int value, int minimum, const char* name) {
  if (value < minimum) {
    throw Error(ErrorCode::kInvalidInput, std::string("front end parameter ") + name + " = " + std::to_string(value) +
                                              " must be >= " + std::to_string(minimum));
  }
}

// A polynomial of higher order than this over a 2 cm neighbourhood of ~12 voxel centroids fits
// noise; the bound also keeps the normal equations in a fixed-size matrix.
constexpr int kMaxPolynomialOrder = 4;

// The weighted least-squares fit of the height w(u, v) over the tangent plane at the foot, in
// PCL's term order (u^a v^b for a = 0..order, b = 0..order-a), with Gaussian weights
// exp(-d^2 / r^2) of the distance to the foot. Returns the fitted height at the foot (the
// constant term), NaN when the fit is degenerate. The number of coefficients is a template
// argument so that the normal equations are fixed-size matrices the compiler unrolls: at the
// default order 2 that halved the smoothing stage's time.
template <int Coefficients>
double fitHeightAtFoot(const XyzCloud& cloud, const std::vector<int>& neighbours, const Eigen::Vector3d& foot,
                       const Eigen::Vector3d& normal, int order, double inverse_squared_radius) {
  using Terms = Eigen::Matrix<double, Coefficients, 1>;
  const Eigen::Vector3d v_axis = normal.unitOrthogonal();
  const Eigen::Vector3d u_axis = normal.cross(v_axis);
  Eigen::Matrix<double, Coefficients, Coefficients> lhs = Eigen::Matrix<double, Coefficients, Coefficients>::Zero();
  Terms rhs = Terms::Zero(), terms;
  for (int n : neighbours) {
    const Eigen::Vector3d d = cloud[static_cast<size_t>(n)].getVector3fMap().cast<double>() - foot;
    const double weight = std::exp(-d.squaredNorm() * inverse_squared_radius);
    const double u = d.dot(u_axis), v = d.dot(v_axis), w = d.dot(normal);
    int j = 0;
    double u_power = 1.0;
    for (int a = 0; a <= order; ++a) {
      double v_power = 1.0;
      for (int b = 0; b <= order - a; ++b) {
        terms[j++] = u_power * v_power;
        v_power *= v;
      }
      u_power *= u;
    }
    lhs.template selfadjointView<Eigen::Lower>().rankUpdate(terms, weight);
    rhs.noalias() += weight * w * terms;
  }
  return lhs.template selfadjointView<Eigen::Lower>().llt().solve(rhs)[0];
}

// pcl::MovingLeastSquares' projection of point i (order >= 2, simple projection, no upsampling),
// computed from the neighbours the grid found: the point goes onto the plane through its
// neighbours' centroid, then along the plane's normal onto the polynomial fit at its foot
// (fitHeightAtFoot). Orders 0 and 1, and neighbourhoods with fewer points than coefficients,
// stop at the plane.
Eigen::Vector3d projectMls(const XyzCloud& cloud, int i, const std::vector<int>& neighbours,
                           const SmoothingParams& params) {
  const Eigen::Vector3d query = cloud[static_cast<size_t>(i)].getVector3fMap().cast<double>();
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (int n : neighbours) centroid += cloud[static_cast<size_t>(n)].getVector3fMap().cast<double>();
  centroid /= static_cast<double>(neighbours.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (int n : neighbours) {
    const Eigen::Vector3d d = cloud[static_cast<size_t>(n)].getVector3fMap().cast<double>() - centroid;
    covariance.noalias() += d * d.transpose();
  }
  // pcl::eigen33, the solver PCL's MLS uses, so the plane is PCL's also for degenerate
  // (collinear, coincident) neighbourhoods.
  double smallest = 0;
  Eigen::Vector3d normal;
  pcl::eigen33(covariance, smallest, normal);
  if (!normal.allFinite() || std::abs(normal.norm() - 1.0) > 1e-6) return query;
  const Eigen::Vector3d foot = query - (query - centroid).dot(normal) * normal;
  const int order = params.polynomial_order;
  const int coefficients = (order + 1) * (order + 2) / 2;
  if (order < 2 || static_cast<int>(neighbours.size()) < coefficients) return foot;

  const double inverse_squared_radius = 1.0 / (static_cast<double>(params.radius) * params.radius);
  double height = 0;
  switch (order) {
    case 2: height = fitHeightAtFoot<6>(cloud, neighbours, foot, normal, order, inverse_squared_radius); break;
    case 3: height = fitHeightAtFoot<10>(cloud, neighbours, foot, normal, order, inverse_squared_radius); break;
    default: height = fitHeightAtFoot<15>(cloud, neighbours, foot, normal, order, inverse_squared_radius); break;
  }
  static_assert(kMaxPolynomialOrder == 4, "fitHeightAtFoot is instantiated for every order up to the maximum");
  // A degenerate fit leaves the point on its plane, as PCL does when the coefficient is NaN. A
  // nearly singular one can also be finite and huge: on the service tests' synthetic 640x480
  // frame such points landed far away, and the normals stage took 17-29 s instead of 0.1 s
  // (see NeighbourGrid::build). A height beyond the search radius is no surface through these
  // neighbours either.
  if (!std::isfinite(height) || std::abs(height) > params.radius) return foot;
  return foot + height * normal;
}

// Occluding contours (detectOccludingContourPixels) on the range image.

// Pixels with no return (no point, or a point whose range is NaN) hold this. Ranges are norms,
// so never negative: the nearest of a pixel's neighbours is negative exactly when one of them
// has no return, and that one comparison sends a pixel from the per-row formula to the full
// test.
constexpr float kNoReturn = -1.0f;
bool hasReturn(float range) { return range >= 0.0f; }

constexpr int kContourDirections[8][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {1, -1}, {-1, 1}, {-1, -1}};

// ContourParams' test of one pixel, valid anywhere in the image: along each direction, the
// pixels up to `window` away that are inside the image decide; when none of them has a
// return, the first one with a return within max_gap does, and when there is none either, it
// is a silhouette against empty space unless the image ended before max_gap.
bool isOccludingContourPixel(const std::vector<float>& range, int width, int height, int row, int col,
                             const ContourParams& params) {
  const float* center = &range[static_cast<size_t>(row) * width + col];
  const float r = *center;
  if (!hasReturn(r)) return false;
  const float jump = std::max(params.min_jump, params.relative_jump * r);
  bool occluding = false, shadow = false;
  constexpr int kNoBorder = std::numeric_limits<int>::max();
  for (const auto& d : kContourDirections) {
    // Steps along d that stay inside the image.
    const int inside = std::min(d[0] > 0 ? width - 1 - col : d[0] < 0 ? col : kNoBorder,
                                d[1] > 0 ? height - 1 - row : d[1] < 0 ? row : kNoBorder);
    const int last = std::min(params.max_gap, inside);
    const std::ptrdiff_t stride = d[1] * static_cast<std::ptrdiff_t>(width) + d[0];
    bool seen = false;
    int step = 1;
    // Without branches on the data: which of these pixels have a return is unpredictable.
    for (const int window_end = std::min(params.window, last); step <= window_end; ++step) {
      const float other = center[step * stride];
      const bool returned = hasReturn(other);
      seen |= returned;
      occluding |= returned & (other - r > jump);
      shadow |= returned & (r - other > jump);
    }
    for (; !seen && step <= last; ++step) {
      const float other = center[step * stride];
      if (hasReturn(other)) {
        seen = true;
        occluding |= other - r > jump;
        shadow |= r - other > jump;
      }
    }
    // No return all the way across the gap: a silhouette against empty space.
    occluding |= !seen && inside >= params.max_gap;
  }
  return occluding && !shadow;
}

// Folds the 8 pixels `step` away from each pixel in [begin, end) of the row `center` into
// `nearest` and `farthest`. A function of its own so that __restrict can tell GCC the outputs
// are not the range image: otherwise the loop would need 16 run-time alias checks, and above
// 10 (--param vect-max-version-for-alias-checks) GCC does not vectorise it.
void foldContourNeighbours(const float* center, std::ptrdiff_t width, int step, int begin, int end,
                           float* __restrict nearest, float* __restrict farthest) {
  const float* neighbour[8];
  for (int k = 0; k < 8; ++k) {
    neighbour[k] = center + step * (kContourDirections[k][1] * width + kContourDirections[k][0]);
  }
  for (int col = begin; col < end; ++col) {
    float lo = nearest[col], hi = farthest[col];
    for (int k = 0; k < 8; ++k) {
      lo = std::min(lo, neighbour[k][col]);
      hi = std::max(hi, neighbour[k][col]);
    }
    nearest[col] = lo;
    farthest[col] = hi;
  }
}

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

XyzCloud::Ptr downsample(const Cloud& cloud, const DownsampleParams& params) {
  requirePositive(params.leaf_size, "downsample.leaf_size");
  XyzCloud::Ptr out(new XyzCloud);
  if (cloud.empty()) return out;
  voxelCentroids(cloud, params.leaf_size, *out);
  out->width = static_cast<uint32_t>(out->size());
  out->height = 1;
  out->is_dense = true;
  return out;
}

XyzCloud::Ptr smooth(const XyzCloud& cloud, const SmoothingParams& params) {
  requirePositive(params.radius, "smoothing.radius");
  if (params.polynomial_order < 0 || params.polynomial_order > kMaxPolynomialOrder) {
    throw Error(ErrorCode::kInvalidInput,
                "front end parameter smoothing.polynomial_order = " + std::to_string(params.polynomial_order) +
                    " must be within 0.." + std::to_string(kMaxPolynomialOrder));
  }
  XyzCloud::Ptr out(new XyzCloud);
  if (cloud.empty()) return out;
  const NeighbourGrid grid(cloud, params.radius);
  std::vector<Eigen::Vector3f> smoothed(cloud.size());
  std::vector<uint8_t> kept(cloud.size(), 0);
  grid.forEachPoint(params.radius, [&](int i, const std::vector<int>& neighbours) {
    // As pcl::MovingLeastSquares: fewer than 3 neighbours carry no surface and are dropped.
    if (neighbours.size() < 3) return;
    const Eigen::Vector3d projected = projectMls(cloud, i, neighbours, params);
    if (!projected.allFinite()) return;
    smoothed[static_cast<size_t>(i)] = projected.cast<float>();
    kept[static_cast<size_t>(i)] = 1;
  });
  out->reserve(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (kept[i]) out->push_back(pcl::PointXYZ(smoothed[i].x(), smoothed[i].y(), smoothed[i].z()));
  }
  out->width = static_cast<uint32_t>(out->size());
  out->height = 1;
  out->is_dense = true;
  return out;
}

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

KeypointMethod resolveKeypointMethod(KeypointMethod method, const Scene& scene) {
  if (method != KeypointMethod::kAuto) return method;
  return scene.pixel_index.empty() ? KeypointMethod::kBoundary : KeypointMethod::kOccludingContour;
}

std::vector<int> detectOccludingContourPixels(const Scene& scene, const ContourParams& params) {
  requireAtLeast(params.window, 1, "keypoints.contour.window");
  requireAtLeast(params.max_gap, params.window, "keypoints.contour.max_gap (at least the window)");
  requirePositive(params.min_jump, "keypoints.contour.min_jump");
  if (!(params.relative_jump >= 0.0f && std::isfinite(params.relative_jump))) {
    throw Error(ErrorCode::kInvalidInput, "front end parameter keypoints.contour.relative_jump = " +
                                              std::to_string(params.relative_jump) + " must be >= 0 and finite");
  }
  const int width = scene.image_width, height = scene.image_height;
  const size_t pixels = static_cast<size_t>(std::max(width, 0)) * static_cast<size_t>(std::max(height, 0));
  if (scene.pixel_index.empty() || pixels == 0 || !scene.cloud || scene.pixel_index.size() != scene.cloud->size()) {
    throw Error(ErrorCode::kInvalidInput,
                scene.source + ": occluding-contour keypoints need an organized scene (a depth image or an organized "
                               "cloud), got " + std::to_string(width) + "x" + std::to_string(height) + " pixels and " +
                               std::to_string(scene.pixel_index.size()) + " pixel indices for " +
                               std::to_string(scene.cloud ? scene.cloud->size() : 0) + " points");
  }
  std::vector<float> range(pixels, kNoReturn);
  for (size_t i = 0; i < scene.pixel_index.size(); ++i) {
    const int pixel = scene.pixel_index[i];
    if (pixel < 0 || static_cast<size_t>(pixel) >= pixels) {
      throw Error(ErrorCode::kInvalidInput, scene.source + ": pixel index " + std::to_string(pixel) + " is outside the " +
                                                std::to_string(width) + "x" + std::to_string(height) + " image");
    }
    const float r = ((*scene.cloud)[i].getVector3fMap() - scene.sensor_origin).norm();
    range[pixel] = std::isnan(r) ? kNoReturn : r;
  }
  // Most pixels have all 8 * window neighbours inside the image and with a return. Their scan
  // stops at the window in every direction, and an edge is then "some neighbour farther than
  // r + jump, none nearer than r - jump". A rounded subtraction never reverses an order, so
  // comparing the farthest and the nearest neighbour decides, and finding those vectorises
  // over whole rows. The other pixels (the image border, next to a hole) take the full test.
  const int window = params.window;
  const float min_jump = params.min_jump, relative_jump = params.relative_jump;
  std::vector<uint8_t> is_edge(pixels, 0);
#pragma omp parallel
  {
    // Each thread's buffers for its current row.
    std::vector<float> nearest(static_cast<size_t>(width)), farthest(static_cast<size_t>(width));
    std::vector<uint8_t> look_across(static_cast<size_t>(width));
#pragma omp for schedule(dynamic, 16)
    for (int row = 0; row < height; ++row) {
      const float* row_range = &range[static_cast<size_t>(row) * width];
      uint8_t* row_edge = &is_edge[static_cast<size_t>(row) * width];
      // Columns [begin, end) have their whole window inside the image.
      const bool inner_row = row >= window && row < height - window;
      const int begin = inner_row ? std::min(window, width) : width;
      const int end = inner_row ? std::max(begin, width - window) : width;
      std::fill(nearest.begin() + begin, nearest.begin() + end, std::numeric_limits<float>::infinity());
      std::fill(farthest.begin() + begin, farthest.begin() + end, -std::numeric_limits<float>::infinity());
      for (int step = 1; step <= window; ++step) {
        foldContourNeighbours(row_range, width, step, begin, end, nearest.data(), farthest.data());
      }
      for (int col = begin; col < end; ++col) {
        const float r = row_range[col];
        const float jump = std::max(min_jump, relative_jump * r);
        row_edge[col] = hasReturn(r) & (farthest[col] - r > jump) & !(r - nearest[col] > jump);
        look_across[col] = hasReturn(r) & !hasReturn(nearest[col]);
      }
      // Few pixels look across a hole (5% of those with a return on tum_desk): memchr finds
      // them faster than a loop testing every flag.
      const uint8_t* const flags = look_across.data();
      for (const uint8_t* p = flags + begin; p < flags + end; ++p) {
        p = static_cast<const uint8_t*>(std::memchr(p, 1, static_cast<size_t>(flags + end - p)));
        if (p == nullptr) break;
        const int col = static_cast<int>(p - flags);
        row_edge[col] = isOccludingContourPixel(range, width, height, row, col, params);
      }
      for (int col = 0; col < begin; ++col) {
        row_edge[col] = isOccludingContourPixel(range, width, height, row, col, params);
      }
      for (int col = end; col < width; ++col) {
        row_edge[col] = isOccludingContourPixel(range, width, height, row, col, params);
      }
    }
  }
  std::vector<int> edges;
  for (size_t i = 0; i < scene.pixel_index.size(); ++i) {
    if (is_edge[scene.pixel_index[i]]) edges.push_back(static_cast<int>(i));
  }
  return edges;
}

namespace {

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
  if (resolveKeypointMethod(params.method, scene) == KeypointMethod::kBoundary) {
    keypoints = detectBoundaryKeypoints(surface, params);
  } else {
    keypoints = nearestSurfacePoints(surface, *scene.cloud, detectOccludingContourPixels(scene, params.contour),
                                     leaf_size);
  }
  return thinKeypoints(surface, keypoints, params.min_spacing);
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

Features describe(const Surface& surface, const std::vector<int>& keypoints, const ShotParams& params) {
  return computeShot(surface, keypoints, params);
}

FrontEndResult extractFeatures(const Scene& scene, const FrontEndParams& params, bool apply_smoothing,
                               StageTimings* timings, const ShouldStop& should_stop) {
  if (!scene.cloud || scene.cloud->empty()) {
    throw Error(ErrorCode::kInvalidInput, scene.source + ": the scene has no points");
  }
  FrontEndResult result;
  result.input_points = scene.cloud->size();
  throwIfStopped(should_stop, "front end start");
  XyzCloud::Ptr points;
  {
    ScopedStage stage(timings, "downsample");
    points = downsample(*scene.cloud, params.downsample);
  }
  throwIfStopped(should_stop, "downsample");
  if (apply_smoothing && params.smoothing.enabled) {
    {
      ScopedStage stage(timings, "smooth");
      points = smooth(*points, params.smoothing);
    }
    throwIfStopped(should_stop, "smooth");
  }
  result.surface_points = points->size();
  std::vector<int> keypoints;
  if (resolveKeypointMethod(params.keypoints.method, scene) == KeypointMethod::kBoundary) {
    {
      ScopedStage stage(timings, "normals");
      result.surface = estimateNormals(*points, params.normals, scene.sensor_origin);
    }
    throwIfStopped(should_stop, "normals");
    {
      ScopedStage stage(timings, "keypoints");
      keypoints = detectKeypoints(scene, *result.surface, params.keypoints, params.downsample.leaf_size);
    }
    throwIfStopped(should_stop, "keypoints");
  } else {
    // Keypoints first, then the normals SHOT reads around them.
    std::optional<NormalEstimator> normals;
    {
      ScopedStage stage(timings, "keypoints");
      normals.emplace(*points, params.normals, scene.sensor_origin);
      keypoints = detectContourKeypoints(scene, *normals, params.keypoints, params.downsample.leaf_size);
    }
    throwIfStopped(should_stop, "keypoints");
    {
      ScopedStage stage(timings, "normals");
      normals->computeNear(keypoints, params.shot.radius);
      std::vector<int> index_in_surface;
      result.surface = normals->surface(&index_in_surface);
      for (int& k : keypoints) k = index_in_surface[static_cast<size_t>(k)];
    }
    throwIfStopped(should_stop, "normals");
  }
  result.keypoint_candidates = keypoints.size();
  {
    ScopedStage stage(timings, "describe");
    result.features = describe(*result.surface, keypoints, params.shot);
  }
  return result;
}

}  // namespace ism
