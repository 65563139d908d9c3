#include "core/frontend/smoothing.h"

#include <pcl/common/eigen.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <string>
#include <vector>

#include "core/common/error.h"
#include "core/frontend/neighbour_grid.h"
#include "core/frontend/param_checks.h"

namespace ism {
namespace {

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

}  // namespace

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

}  // namespace ism
