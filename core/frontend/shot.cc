#include "core/frontend/shot.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "core/common/cpu_features.h"
#include "core/common/error.h"
#include "core/frontend/neighbour_grid.h"

namespace ism {
namespace {

// PCL's layout: 32 volumes (8 azimuth sectors x 2 elevations x 2 shells), each a histogram of
// the cosine between the neighbour's normal and the LRF's z over 10 bins. A cosine of exactly 1
// lands one past them, so each volume holds 11 floats.
constexpr int kCosineBins = 10;
constexpr int kVolumeLength = kCosineBins + 1;
constexpr int kVolumes = 32;
static_assert(kVolumes * kVolumeLength == kShotLength, "PCL's SHOT352 layout");

// shot.hpp's constants, with its digits.
constexpr double kRad45 = 0.78539816339744830961566084581988;
constexpr double kRad90 = 1.5707963267948966192313216916398;
constexpr double kRad135 = 2.3561944901923449288469825374596;
constexpr double kRadPi78 = 2.7488935718910690836548129603691;

// Below these PCL treats a support point as the keypoint itself (shot.hpp areEquals) and an LRF
// coordinate as zero.
constexpr double kZeroDistance = 1e-15;
constexpr double kZeroCoordinate = 1e-30;

// One keypoint's support, in the grid's search order: PCL breaks sign ties in the LRF by the
// order of the neighbours and adds their votes in that order, so keeping it keeps PCL's floats.
struct Support {
  std::vector<int> indices;
  std::vector<float> squared_distances;
  // Per support point: point - keypoint in float (as PCL subtracts), the normal, and the
  // distance as PCL takes it, the square root of the float squared distance in double.
  std::vector<float> dx, dy, dz, nx, ny, nz;
  std::vector<double> distance;
  std::vector<uint8_t> is_centre, normal_finite;
  std::vector<Eigen::Vector3d> lrf_deltas;  // of the points that are not the keypoint, in order
  // Per support point, its coordinates in the LRF and the cosine of its normal with the LRF's z.
  std::vector<double> x, y, z, normal_cosine;
  // Per support point, the bins it votes in (its own and its neighbours in cosine, shell,
  // elevation and azimuth) and its shares.
  std::array<std::vector<double>, 5> vote_bins;
  std::array<std::vector<float>, 5> vote_shares;
  std::array<float, kShotLength + 1> bins;

  void gather(const Surface& surface, const Eigen::Vector3f& centre) {
    const size_t n = indices.size();
    for (auto* column : {&dx, &dy, &dz, &nx, &ny, &nz}) column->resize(n);
    distance.resize(n);
    is_centre.resize(n);
    normal_finite.resize(n);
    for (size_t j = 0; j < n; ++j) {
      const pcl::PointNormal& p = surface[static_cast<size_t>(indices[j])];
      dx[j] = p.x - centre.x();
      dy[j] = p.y - centre.y();
      dz[j] = p.z - centre.z();
      nx[j] = p.normal_x;
      ny[j] = p.normal_y;
      nz[j] = p.normal_z;
      is_centre[j] = p.getVector3fMap() == centre;
      normal_finite[j] = std::isfinite(p.normal_x) && std::isfinite(p.normal_y) && std::isfinite(p.normal_z);
    }
    for (size_t j = 0; j < n; ++j) distance[j] = std::sqrt(static_cast<double>(squared_distances[j]));
  }
};

// PCL's getLocalRF (shot_lrf.hpp): the covariance of the support weighted by (R - distance), its
// eigenvectors, x and z pointing to the side holding most of the support, y = z cross x.
bool localReferenceFrame(Support& support, double radius, Eigen::Matrix3f& lrf) {
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  double weight_sum = 0.0;
  auto& deltas = support.lrf_deltas;
  deltas.clear();
  for (size_t j = 0; j < support.indices.size(); ++j) {
    if (support.is_centre[j]) continue;
    const Eigen::Vector3d v(support.dx[j], support.dy[j], support.dz[j]);
    const double weight = radius - support.distance[j];
    // Eigen evaluates PCL's weight * (v v^T) as (weight v) v^T; the solver reads the lower half.
    const Eigen::Vector3d wv = weight * v;
    covariance(0, 0) += wv[0] * v[0];
    covariance(1, 0) += wv[1] * v[0];
    covariance(2, 0) += wv[2] * v[0];
    covariance(1, 1) += wv[1] * v[1];
    covariance(2, 1) += wv[2] * v[1];
    covariance(2, 2) += wv[2] * v[2];
    weight_sum += weight;
    deltas.push_back(v);
  }
  const int valid = static_cast<int>(deltas.size());
  if (valid < 5) return false;
  covariance /= weight_sum;
  covariance(0, 1) = covariance(1, 0);
  covariance(0, 2) = covariance(2, 0);
  covariance(1, 2) = covariance(2, 1);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  if (!solver.eigenvalues().allFinite()) return false;

  // Each axis points to the side of the majority; a tie is decided by the 5 points around the
  // middle of the search order, as PCL does.
  const auto disambiguate = [&](Eigen::Vector3d axis) {
    const auto dot = [&](const Eigen::Vector3d& v) { return (v[0] * axis[0] + v[1] * axis[1]) + v[2] * axis[2]; };
    int plus = 0;
    for (const Eigen::Vector3d& v : deltas) plus += dot(v) >= 0.0;
    plus = 2 * plus - valid;
    if (plus == 0) {
      const int middle = valid / 2;
      for (int i = -2; i <= 2; ++i) plus += dot(deltas[static_cast<size_t>(middle - i)]) > 0.0;
      if (plus < 3) axis = -axis;
    } else if (plus < 0) {
      axis = -axis;
    }
    return axis;
  };
  const Eigen::Vector3f x = disambiguate(solver.eigenvectors().col(2)).cast<float>();
  const Eigen::Vector3f z = disambiguate(solver.eigenvectors().col(0)).cast<float>();
  lrf.row(0) = x;
  lrf.row(2) = z;
  lrf.row(1) = z.cross(x);
  return lrf.allFinite();
}

// v limited to [-limit, limit] as PCL limits cosines and offsets. Selects between values:
// std::min and std::max return references, which keep GCC from vectorising the loops below.
inline double clamp(double v, double limit) {
  const double below = v > limit ? limit : v;
  return below < -limit ? -limit : below;
}

// atan2(y, x) for (x, y) != (0, 0), within 3 ulp (4.4e-16) of glibc's on 2 * 10^7 samples: the
// angle to the nearer axis is reduced to [-pi/8, pi/8], where Cephes' degree 4/5 rational
// (Moshier) is within 1 ulp, and mirrored into place. Every candidate is computed and one
// selected, without branches: a support point's octant is a coin toss for a branch predictor,
// and the loops calling this vectorise. kPiTail is what kRad90 and kPi lack of pi/2 and pi.
inline double fastAtan2(double y, double x) {
  constexpr double kTanPi8 = 0.41421356237309504880;
  constexpr double kPi = 3.1415926535897932384626433832795;
  constexpr double kPiTail = 6.123233995736765886130e-17;
  const double ax = std::abs(x), ay = std::abs(y);
  const double lo = ay < ax ? ay : ax, hi = ax < ay ? ay : ax;
  const bool far = lo > kTanPi8 * hi;  // past pi/8: atan(t) = pi/4 + atan((t - 1) / (t + 1))
  const double far_numerator = lo - hi, far_denominator = lo + hi;
  const double r = (far ? far_numerator : lo) / (far ? far_denominator : hi);
  const double z = r * r;
  const double p = (((-8.750608600031904122785e-1 * z - 1.615753718733365076637e1) * z - 7.500855792314704667340e1) * z -
                    1.228866684490136173410e2) * z - 6.485021904942025371773e1;
  const double q = ((((z + 2.485846490142306297962e1) * z + 1.650270098316988542046e2) * z + 4.328810604912902668951e2) * z +
                    4.853903996359136964868e2) * z + 1.945506571482613964425e2;
  const double near = r + r * (z * p / q);
  const double octant = far ? kRad45 + (near + 0.5 * kPiTail) : near;
  const double swapped = (kRad90 - octant) + kPiTail;
  const double quadrant = ay > ax ? swapped : octant;
  const double mirrored = (kPi - quadrant) + 2 * kPiTail;
  const double half = x < 0 ? mirrored : quadrant;
  return y < 0 ? -half : half;
}

// histogram() is compiled twice, for the x86-64 baseline and for AVX2, and the CPU's features
// pick one at run time (core/common/cpu_features.h). With AVX2 its per-point loop works on 4
// doubles at a time instead of 2, without SSE2's register copies and three-instruction selects.
// The IEEE operations per point are the same, and so are the results.

// PCL's createBinDistanceShape and interpolateSingleChannel (shot.hpp): each support point votes
// for the cosine bin of its normal in its volume, shared linearly with the neighbouring cosine
// bin, shell, elevation and azimuth sector.
//
// Where each point votes and how much is worked out first, in a loop over the support that
// vectorises, with the same IEEE operations per point as PCL but for acos and atan2
// (fastAtan2). PCL's branches become selects: every share is 1 - |d| for the point's own cell
// plus |d| for the neighbouring one when the point lies on its side, which is PCL's
// 1 + d / 1 - d and -= d / += d; a share that PCL does not cast goes to bins[kShotLength], which
// is never read. The votes are then added in the support's order. One point's votes land in
// distinct bins, so each bin receives PCL's floats in PCL's order.
inline __attribute__((always_inline)) void histogramBody(Support& s, double radius, const Eigen::Matrix3f& lrf,
                                                         float* bins) {
  const size_t n = s.indices.size();
  for (auto* column : {&s.x, &s.y, &s.z, &s.normal_cosine}) column->resize(n);
  for (auto& column : s.vote_bins) column.resize(n);
  for (auto& column : s.vote_shares) column.resize(n);
  const float* __restrict dx = s.dx.data();
  const float* __restrict dy = s.dy.data();
  const float* __restrict dz = s.dz.data();
  const float* __restrict nx = s.nx.data();
  const float* __restrict ny = s.ny.data();
  const float* __restrict nz = s.nz.data();
  const double* __restrict distance = s.distance.data();
  double* __restrict lrf_x = s.x.data();
  double* __restrict lrf_y = s.y.data();
  double* __restrict lrf_z = s.z.data();
  double* __restrict normal_cosine = s.normal_cosine.data();
  double* __restrict own_bin = s.vote_bins[0].data();
  double* __restrict cosine_bin = s.vote_bins[1].data();
  double* __restrict shell_bin = s.vote_bins[2].data();
  double* __restrict elevation_bin = s.vote_bins[3].data();
  double* __restrict azimuth_bin = s.vote_bins[4].data();
  float* __restrict own_share = s.vote_shares[0].data();
  float* __restrict cosine_share = s.vote_shares[1].data();
  float* __restrict shell_share = s.vote_shares[2].data();
  float* __restrict elevation_share = s.vote_shares[3].data();
  float* __restrict azimuth_share = s.vote_shares[4].data();
  constexpr int kNoBin = kShotLength;
  const double radius1_2 = radius / 2, radius1_4 = radius / 4, radius3_4 = (radius * 3) / 4;
  const float ax0 = lrf(0, 0), ax1 = lrf(0, 1), ax2 = lrf(0, 2);
  const float ay0 = lrf(1, 0), ay1 = lrf(1, 1), ay2 = lrf(1, 2);
  const float az0 = lrf(2, 0), az1 = lrf(2, 1), az2 = lrf(2, 2);
  // Two loops, as GCC does not vectorise selects after double comparisons in a loop that also
  // converts from float.
#pragma omp simd
  for (size_t j = 0; j < n; ++j) {
    // PCL dots 4-float vectors whose 4th lanes are zero; Eigen's SSE reduction adds lanes
    // 0 + 2 and 1 + 3, and the same association gives the same float.
    const double fx = (dx[j] * ax0 + dz[j] * ax2) + dy[j] * ax1;
    const double fy = (dx[j] * ay0 + dz[j] * ay2) + dy[j] * ay1;
    const double fz = (dx[j] * az0 + dz[j] * az2) + dy[j] * az1;
    lrf_x[j] = std::abs(fx) < kZeroCoordinate ? 0.0 : fx;
    lrf_y[j] = std::abs(fy) < kZeroCoordinate ? 0.0 : fy;
    lrf_z[j] = std::abs(fz) < kZeroCoordinate ? 0.0 : fz;
    normal_cosine[j] = (nx[j] * az0 + nz[j] * az2) + ny[j] * az1;
  }
#pragma omp simd
  for (size_t j = 0; j < n; ++j) {
    const double x = lrf_x[j], y = lrf_y[j], z = lrf_z[j];

    // PCL's volume bits: 8 azimuth sectors of 45 degrees bounded by the axes and the diagonals;
    // PCL's "inclination > 90 degrees" is z <= 0 exactly, as glibc's acos is monotonic and
    // acos(0) rounds to kRad90; the outer shell beyond half the radius. Conditions combine with
    // & and |, and bin numbers are doubles: GCC vectorises selects between doubles after double
    // comparisons, not between ints nor conditional expressions of conditions.
    const bool bit4 = (y > 0) | ((y == 0.0) & (x < 0));
    const bool bit3 = bit4 != ((x > 0) | ((x == 0.0) & (y > 0)));
    const bool same_sign = (x * y > 0) | (x == 0.0);
    const bool x_smaller = std::abs(x) < std::abs(y), x_larger = std::abs(x) > std::abs(y);
    const bool past_diagonal = (same_sign & x_smaller) | (!same_sign & x_larger);
    const bool upper = z > 0;
    const bool outer = distance[j] > radius1_2;
    const double sector = (bit4 ? 4.0 : 0.0) + (bit3 ? 2.0 : 0.0) + (past_diagonal ? 1.0 : 0.0);
    const double volume = 4 * sector + (outer ? 2.0 : 0.0) + (upper ? 1.0 : 0.0);
    const double own = volume * kVolumeLength;

    const double bin_position = ((1.0 + clamp(normal_cosine[j], 1.0)) * kCosineBins) / 2;
    // PCL's floor(position + 0.5) in double arithmetic, which vectorises: adding and removing
    // 2^52 rounds a position in [0, 11) to an integer, and one less if that rounded up.
    const double rounded = bin_position + 0.5;
    const double nearest = (rounded + 0x1p52) - 0x1p52;
    const double step = nearest > rounded ? nearest - 1 : nearest;
    const double cosine_offset = bin_position - step;
    // PCL's (step + 1) % 10 and (step - 1 + 10) % 10.
    const double up = step + 1 >= kCosineBins ? step + 1 - kCosineBins : step + 1;
    const double down = step == 0 ? kCosineBins - 1 : step - 1;
    double weight = 1 - std::abs(cosine_offset);

    const double shell_offset = (distance[j] - (outer ? radius3_4 : radius1_4)) / radius1_2;
    weight += 1 - std::abs(shell_offset);
    const bool other_shell = (outer & (shell_offset <= 0)) | (!outer & (shell_offset >= 0));

    // acos(z / distance) as atan2(sin, cos).
    const double inclination_cosine = clamp(z / distance[j], 1.0);
    const double inclination =
        fastAtan2(std::sqrt((1 - inclination_cosine) * (1 + inclination_cosine)), inclination_cosine);
    const double elevation_offset = (inclination - (upper ? kRad45 : kRad135)) / kRad90;
    weight += 1 - std::abs(elevation_offset);
    const bool other_half = (upper & (elevation_offset >= 0)) | (!upper & (elevation_offset <= 0));

    // PCL leaves the azimuth out for a point on the LRF's z axis, where fastAtan2 is NaN.
    const bool has_azimuth = (x != 0.0) | (y != 0.0);
    const double sector_offset = clamp((fastAtan2(y, x) - (-kRadPi78 + kRad45 * sector)) / kRad45, 0.5);
    weight += has_azimuth ? 1 - std::abs(sector_offset) : 0.0;
    const double next_volume = volume + (sector_offset > 0 ? 4.0 : kVolumes - 4.0);
    const double azimuth_neighbour = next_volume >= kVolumes ? next_volume - kVolumes : next_volume;

    own_bin[j] = own + step;
    own_share[j] = static_cast<float>(weight);
    cosine_bin[j] = own + (cosine_offset > 0 ? up : down);
    cosine_share[j] = static_cast<float>(std::abs(cosine_offset));
    shell_bin[j] = other_shell ? own + (outer ? -2.0 : 2.0) * kVolumeLength + step : kNoBin;
    shell_share[j] = static_cast<float>(std::abs(shell_offset));
    elevation_bin[j] = other_half ? own + (upper ? -1.0 : 1.0) * kVolumeLength + step : kNoBin;
    elevation_share[j] = static_cast<float>(std::abs(elevation_offset));
    azimuth_bin[j] = has_azimuth ? azimuth_neighbour * kVolumeLength + step : kNoBin;
    azimuth_share[j] = static_cast<float>(std::abs(sector_offset));
  }

  std::fill(bins, bins + kShotLength + 1, 0.0f);
  for (size_t j = 0; j < n; ++j) {
    if (!(distance[j] >= kZeroDistance) || !s.normal_finite[j]) continue;
    bins[static_cast<int>(cosine_bin[j])] += cosine_share[j];
    bins[static_cast<int>(shell_bin[j])] += shell_share[j];
    bins[static_cast<int>(elevation_bin[j])] += elevation_share[j];
    bins[static_cast<int>(azimuth_bin[j])] += azimuth_share[j];
    bins[static_cast<int>(own_bin[j])] += own_share[j];
  }
}

void histogramBaseline(Support& s, double radius, const Eigen::Matrix3f& lrf, float* bins) {
  histogramBody(s, radius, lrf, bins);
}

#if ISM_X86_KERNELS
__attribute__((target("avx2"))) void histogramAvx2(Support& s, double radius, const Eigen::Matrix3f& lrf,
                                                   float* bins) {
  histogramBody(s, radius, lrf, bins);
}
#endif

void histogram(Support& s, double radius, const Eigen::Matrix3f& lrf, float* bins) {
#if ISM_X86_KERNELS
  if (cpuHasAvx2()) return histogramAvx2(s, radius, lrf, bins);
#endif
  histogramBaseline(s, radius, lrf, bins);
}

// PCL's normalizeHistogram: unit L2 norm, accumulated in double. False when nothing voted.
bool normalize(const float* bins, float* shot) {
  double norm = 0;
  for (int j = 0; j < kShotLength; ++j) norm += bins[j] * bins[j];
  norm = std::sqrt(norm);
  if (!(norm > 0.0) || !std::isfinite(norm)) return false;
  const float scale = static_cast<float>(norm);
  for (int j = 0; j < kShotLength; ++j) shot[j] = bins[j] / scale;
  return true;
}

}  // namespace

Features computeShot(const Surface& surface, const std::vector<int>& keypoints, const ShotParams& params,
                     std::vector<int>* described) {
  if (!(std::isfinite(params.radius) && params.radius > 0.0f)) {
    throw Error(ErrorCode::kInvalidInput,
                "front end parameter shot.radius = " + std::to_string(params.radius) + " must be positive and finite");
  }
  for (int k : keypoints) {
    if (k < 0 || static_cast<size_t>(k) >= surface.size()) {
      throw Error(ErrorCode::kInvalidInput, "keypoint index " + std::to_string(k) + " is outside the surface of " +
                                                std::to_string(surface.size()) + " points");
    }
  }
  Features features;
  features.descriptors.resize(0, kShotLength);
  if (described != nullptr) described->clear();
  if (keypoints.empty()) return features;

  // PCL's estimators take the radius as a double, (double)params.radius; the grid compares
  // float squared distances with the float radius, as it does behind PCL's estimators (GridSearch).
  const double radius = params.radius;
  const NeighbourGrid grid(surface, params.radius);
  const size_t enough = static_cast<size_t>(std::max(params.min_neighbours, 1));
  const std::ptrdiff_t count = static_cast<std::ptrdiff_t>(keypoints.size());
  std::vector<Eigen::Matrix3f> lrfs(keypoints.size());
  DescriptorMatrix descriptors(count, kShotLength);
  std::vector<uint8_t> kept(keypoints.size(), 0);
#pragma omp parallel
  {
    Support support;
#pragma omp for schedule(dynamic, 8)
    for (std::ptrdiff_t i = 0; i < count; ++i) {
      const Eigen::Vector3f centre = surface[static_cast<size_t>(keypoints[i])].getVector3fMap();
      if (grid.radiusSearch(centre, params.radius, support.indices, support.squared_distances) < enough) continue;
      support.gather(surface, centre);
      if (!localReferenceFrame(support, radius, lrfs[i])) continue;
      histogram(support, radius, lrfs[i], support.bins.data());
      kept[i] = normalize(support.bins.data(), descriptors.row(i).data());
    }
  }

  Eigen::Index rows = 0;
  for (std::ptrdiff_t i = 0; i < count; ++i) {
    if (!kept[i]) continue;
    if (rows != i) descriptors.row(rows) = descriptors.row(i);
    ++rows;
    features.positions.push_back(surface[static_cast<size_t>(keypoints[i])].getVector3fMap());
    features.lrfs.push_back(lrfs[i]);
    if (described != nullptr) described->push_back(keypoints[i]);
  }
  descriptors.conservativeResize(rows, kShotLength);
  features.descriptors = std::move(descriptors);
  return features;
}

}  // namespace ism
