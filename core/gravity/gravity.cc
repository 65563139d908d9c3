#include "core/gravity/gravity.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <random>

#include "core/common/cpu_features.h"
#include "core/common/error.h"
#include "core/common/upright_box.h"

namespace ism {
namespace {

struct Plane {
  Eigen::Vector3f normal = Eigen::Vector3f::UnitZ();
  float offset = 0;  // normal . p = offset on the plane
  float distance(const Eigen::Vector3f& p) const { return normal.dot(p) - offset; }
};

float radians(float degrees) { return degrees * static_cast<float>(M_PI) / 180.0f; }

// The points RANSAC scores its planes on, as three arrays: a plane's support is then counted
// several points at a time (the compiler vectorizes the loop). RANSAC spends most of gravity's time
// there.
struct Coordinates {
  std::vector<float> x, y, z;
  explicit Coordinates(const std::vector<Eigen::Vector3f>& points) {
    x.reserve(points.size());
    y.reserve(points.size());
    z.reserve(points.size());
    for (const auto& p : points) {
      x.push_back(p.x());
      y.push_back(p.y());
      z.push_back(p.z());
    }
  }
  size_t size() const { return x.size(); }
};

struct Support {
  size_t within = 0;  // points within the inlier distance of the plane
  size_t below = 0;   // points farther than the margin under it (counted for the floor only)
};

// A plane's support, counted block by block. Counting stops, the counts then incomplete, once the
// plane can no longer have more than `to_beat` points within `inlier` or (kBelow: the floor) has
// more than `max_below` farther than `below_margin` under it: such a plane loses either way, so the
// search picks the same plane as a full count. The distance is Plane::distance's, in the same
// order of operations (Eigen sums a 3-vector's dot product as x + (y + z)), and no variant fuses a
// multiply with an add, so every CPU counts alike.
template <bool kBelow>
inline __attribute__((always_inline)) Support countSupportBody(const Coordinates& c, const Plane& plane, float inlier,
                                                               float below_margin, size_t to_beat, size_t max_below) {
  constexpr size_t kBlock = 512;
  const float nx = plane.normal.x(), ny = plane.normal.y(), nz = plane.normal.z(), offset = plane.offset;
  const size_t n = c.size();
  const float* x = c.x.data();
  const float* y = c.y.data();
  const float* z = c.z.data();
  Support support;
  for (size_t start = 0; start < n; start += kBlock) {
    const size_t end = std::min(n, start + kBlock);
    unsigned within = 0, below = 0;
    for (size_t i = start; i < end; ++i) {
      const float d = nx * x[i] + (ny * y[i] + nz * z[i]) - offset;
      within += std::abs(d) <= inlier ? 1u : 0u;
      if constexpr (kBelow) below += d < -below_margin ? 1u : 0u;
    }
    support.within += within;
    support.below += below;
    if (support.within + (n - end) <= to_beat || support.below > max_below) break;
  }
  return support;
}

template <bool kBelow>
Support countSupportBaseline(const Coordinates& c, const Plane& plane, float inlier, float below_margin, size_t to_beat,
                             size_t max_below) {
  return countSupportBody<kBelow>(c, plane, inlier, below_margin, to_beat, max_below);
}

#if ISM_X86_KERNELS
template <bool kBelow>
__attribute__((target("avx2"))) Support countSupportAvx2(const Coordinates& c, const Plane& plane, float inlier,
                                                         float below_margin, size_t to_beat, size_t max_below) {
  return countSupportBody<kBelow>(c, plane, inlier, below_margin, to_beat, max_below);
}
#endif

template <bool kBelow>
Support countSupport(const Coordinates& c, const Plane& plane, float inlier, float below_margin, size_t to_beat,
                     size_t max_below) {
#if ISM_X86_KERNELS
  if (cpuHasAvx2()) return countSupportAvx2<kBelow>(c, plane, inlier, below_margin, to_beat, max_below);
#endif
  return countSupportBaseline<kBelow>(c, plane, inlier, below_margin, to_beat, max_below);
}

// Up to `count` points spread over the cloud (every n-th), so that scoring a plane costs the
// same on a 300k-point frame as on a 50k-point room sample.
std::vector<Eigen::Vector3f> spreadSample(const std::vector<Eigen::Vector3f>& points, size_t count) {
  if (points.size() <= count) return points;
  std::vector<Eigen::Vector3f> out;
  out.reserve(count);
  const double step = static_cast<double>(points.size()) / static_cast<double>(count);
  for (size_t i = 0; i < count; ++i) out.push_back(points[static_cast<size_t>(static_cast<double>(i) * step)]);
  return out;
}

// The least-squares plane of the points within `distance` of `plane`, normal on the same side.
Plane refine(const Plane& plane, const std::vector<Eigen::Vector3f>& points, float distance) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  size_t n = 0;
  for (const auto& p : points) {
    if (std::abs(plane.distance(p)) <= distance) {
      mean += p.cast<double>();
      ++n;
    }
  }
  if (n < 3) return plane;
  mean /= static_cast<double>(n);
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const auto& p : points) {
    if (std::abs(plane.distance(p)) > distance) continue;
    const Eigen::Vector3d d = p.cast<double>() - mean;
    covariance += d * d.transpose();
  }
  Eigen::Vector3f normal = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance).eigenvectors().col(0).cast<float>();
  if (normal.dot(plane.normal) < 0) normal = -normal;
  return {normal, normal.dot(mean.cast<float>())};
}

float percentile(std::vector<float> values, float fraction) {
  if (values.empty()) return 0;
  const auto at = values.begin() + static_cast<long>(fraction * static_cast<float>(values.size() - 1));
  std::nth_element(values.begin(), at, values.end());
  return *at;
}

// The floor: among planes within `max_angle` of `prior_up` (normals turned towards it), the one
// with most points that has almost none below it.
std::optional<Plane> findFloor(const std::vector<Eigen::Vector3f>& sample, const Eigen::Vector3f& prior_up,
                               float max_angle, bool normal_is_prior, const GravityParams& params) {
  if (sample.size() < 3) return std::nullopt;
  std::mt19937 rng(params.seed);
  std::uniform_int_distribution<size_t> pick(0, sample.size() - 1);
  const float min_cos = std::cos(max_angle);
  const auto min_support = static_cast<size_t>(params.min_floor_fraction * static_cast<float>(sample.size()));
  const auto max_below = static_cast<size_t>(params.max_below_fraction * static_cast<float>(sample.size()));
  std::optional<Plane> best;
  size_t best_support = std::max<size_t>(min_support, 3);
  const Coordinates coordinates(sample);
  // Besides planes through three points, planes square to the prior through one: where the prior
  // is nearly right (a map written z-up, a levelled robot) one point on the floor finds it, even
  // when the floor holds too few points for three of them to be drawn at once; the winner's normal
  // is then fitted to its inliers (refine).
  const int iterations = params.iterations + (normal_is_prior ? 0 : params.prior_iterations);
  for (int it = 0; it < iterations; ++it) {
    Plane plane;
    const Eigen::Vector3f& a = sample[pick(rng)];
    if (normal_is_prior || it >= params.iterations) {
      // Up is known: a horizontal plane is fixed by one point.
      plane.normal = prior_up;
    } else {
      const Eigen::Vector3f n = (sample[pick(rng)] - a).cross(sample[pick(rng)] - a);
      if (!(n.norm() > 1e-9f)) continue;
      plane.normal = n.normalized();
      if (plane.normal.dot(prior_up) < 0) plane.normal = -plane.normal;
      if (plane.normal.dot(prior_up) < min_cos) continue;
    }
    plane.offset = plane.normal.dot(a);
    const Support support =
        countSupport<true>(coordinates, plane, params.inlier_distance, params.below_margin, best_support, max_below);
    if (support.within > best_support && support.below <= max_below) {
      best_support = support.within;
      best = plane;
    }
  }
  if (!best) return std::nullopt;
  Plane refined = refine(*best, sample, params.inlier_distance);
  if (normal_is_prior) {
    // A given up is not second-guessed: only the floor's level is refined.
    double level = 0;
    size_t n = 0;
    for (const auto& p : sample) {
      if (std::abs(best->distance(p)) <= params.inlier_distance) {
        level += prior_up.dot(p);
        ++n;
      }
    }
    return Plane{prior_up, static_cast<float>(level / static_cast<double>(n))};
  }
  return refined.normal.dot(prior_up) >= min_cos ? refined : *best;
}

// How far from a plane its points may lie: the sensor's noise grows with the square of the range
// (NoiseParams' model of the Kinect), so a wall 4 m away is a band several centimetres thick.
struct Tolerance {
  Eigen::Vector3f sensor;
  const GravityParams& params;
  float operator()(const Eigen::Vector3f& p) const {
    const float range = (p - sensor).norm();
    const float sigma = 0.0012f + 0.0019f * (range - 0.4f) * (range - 0.4f);
    return std::max(params.inlier_distance, params.noise_sigmas * sigma);
  }
};

struct Wall {
  Plane plane;
  float along_lo, along_hi;    // extent of its points along the floor
  float height_lo, height_hi;  // and along up
};

// Walls: vertical planes (through two points and up) with most support whose points span a
// wall's height and width. A large vertical face that is not a wall (a wardrobe is, for the
// purpose) is set aside and the search goes on.
std::vector<Wall> findWalls(std::vector<Eigen::Vector3f> free, const Eigen::Vector3f& up, const Tolerance& tolerance,
                            const GravityParams& params) {
  std::vector<Wall> walls;
  std::mt19937 rng(params.seed + 1);
  const float max_sin = std::sin(radians(params.wall_tilt_deg));
  const size_t min_support = std::max<size_t>(50, free.size() / 50);
  for (int attempt = 0; attempt < 2 * params.max_walls && static_cast<int>(walls.size()) < params.max_walls; ++attempt) {
    if (free.size() < min_support) break;
    std::uniform_int_distribution<size_t> pick(0, free.size() - 1);
    Plane best;
    size_t best_support = 0;
    const Coordinates coordinates(free);
    for (int it = 0; it < params.iterations; ++it) {
      const Eigen::Vector3f& a = free[pick(rng)];
      Eigen::Vector3f along = free[pick(rng)] - a;
      along -= up * up.dot(along);
      if (!(along.norm() > 0.05f)) continue;
      Plane plane;
      plane.normal = up.cross(along).normalized();
      plane.offset = plane.normal.dot(a);
      const size_t support = countSupport<false>(coordinates, plane, params.inlier_distance, 0, best_support, 0).within;
      if (support > best_support) {
        best_support = support;
        best = plane;
      }
    }
    if (best_support < min_support) break;
    Plane plane = refine(best, free, params.inlier_distance);
    if (std::abs(plane.normal.dot(up)) > max_sin) plane = best;
    const Eigen::Vector3f along = up.cross(plane.normal).normalized();
    std::vector<float> heights, alongs;
    std::vector<Eigen::Vector3f> rest;
    for (const auto& p : free) {
      const float d = std::abs(plane.distance(p));
      if (d <= params.inlier_distance) {
        heights.push_back(up.dot(p));
        alongs.push_back(along.dot(p));
      }
      if (d > tolerance(p)) rest.push_back(p);
    }
    Wall wall{plane, percentile(alongs, 0.02f), percentile(alongs, 0.98f), percentile(heights, 0.02f),
              percentile(heights, 0.98f)};
    if (wall.height_hi - wall.height_lo >= params.wall_min_height && wall.along_hi - wall.along_lo >= params.wall_min_width) {
      walls.push_back(wall);
    }
    free = std::move(rest);
  }
  return walls;
}

}  // namespace

GravityResult estimateGravity(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector3f& sensor_origin,
                              const Eigen::Vector3f& sensor_up, const std::optional<Eigen::Vector3f>& given_up,
                              const GravityParams& params) {
  if (given_up && !(given_up->allFinite() && given_up->norm() > 1e-6f)) {
    throw Error(ErrorCode::kInvalidInput, "the up vector must be finite and non-zero");
  }
  GravityResult result;
  result.labels.assign(points.size(), PlaneLabel::kNone);
  Gravity& g = result.gravity;
  const std::vector<Eigen::Vector3f> sample = spreadSample(points, params.sample_points);
  if (given_up) {
    g.up = given_up->normalized();
    g.source = UpSource::kGiven;
  } else {
    g.up = sensor_up.normalized();
    g.source = UpSource::kAssumed;
  }
  std::optional<Plane> floor = findFloor(sample, g.up, radians(given_up ? params.given_up_tolerance_deg : params.max_tilt_deg),
                                         given_up.has_value(), params);
  if (floor) {
    if (!given_up) {
      g.up = floor->normal;
      g.source = UpSource::kFloor;
    }
    g.floor_level = floor->offset;
  }

  const Tolerance tolerance{sensor_origin, params};
  std::vector<Eigen::Vector3f> free;
  for (const auto& p : sample) {
    if (!g.hasFloor() || g.height(p) > tolerance(p)) free.push_back(p);
  }
  const std::vector<Wall> walls = findWalls(std::move(free), g.up, tolerance, params);
  g.walls = static_cast<int>(walls.size());
  constexpr float kMargin = 0.1f;  // a wall's points a little beyond its sampled extent
  std::vector<Eigen::Vector3f> wall_alongs;
  for (const Wall& w : walls) wall_alongs.push_back(g.up.cross(w.plane.normal).normalized());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    const float tol = tolerance(p);
    if (g.hasFloor() && std::abs(g.height(p)) <= tol) {
      result.labels[i] = PlaneLabel::kFloor;
      ++g.floor_points;
      continue;
    }
    for (size_t k = 0; k < walls.size(); ++k) {
      const Wall& w = walls[k];
      if (std::abs(w.plane.distance(p)) > tol) continue;
      const float along = wall_alongs[k].dot(p), height = g.up.dot(p);
      if (along < w.along_lo - kMargin || along > w.along_hi + kMargin || height < w.height_lo - kMargin ||
          height > w.height_hi + kMargin) {
        continue;
      }
      result.labels[i] = PlaneLabel::kWall;
      ++g.wall_points;
      break;
    }
  }
  return result;
}

}  // namespace ism
