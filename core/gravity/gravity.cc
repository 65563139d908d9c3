#include "core/gravity/gravity.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <optional>
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

struct Floor {
  Plane plane;
  size_t support = 0;  // sample points within the inlier distance of the plane found (before refine)
};

// The floor: among planes within `max_angle` of `prior_up` (normals turned towards it), the one
// with most points that has almost none below it.
std::optional<Floor> findFloor(const std::vector<Eigen::Vector3f>& sample, const Eigen::Vector3f& prior_up,
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
    // Square to a given up: only the floor's level is refined.
    double level = 0;
    size_t n = 0;
    for (const auto& p : sample) {
      if (std::abs(best->distance(p)) <= params.inlier_distance) {
        level += prior_up.dot(p);
        ++n;
      }
    }
    return Floor{Plane{prior_up, static_cast<float>(level / static_cast<double>(n))}, best_support};
  }
  return Floor{refined.normal.dot(prior_up) >= min_cos ? refined : *best, best_support};
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

// Square cells over a plane, along the floor and up, with one cell of margin round the extent
// they are laid over: where a wall's points lie on it, and which of them make a surface.
struct CellGrid {
  float along0 = 0, height0 = 0, cell = 0;
  int cols = 0, rows = 0;
  // Nothing where there would be absurdly many cells (no room is 300 m long).
  static std::optional<CellGrid> around(const Eigen::Vector2f& lo, const Eigen::Vector2f& hi, float cell) {
    CellGrid g;
    g.cell = cell;
    g.along0 = lo.x() - cell;
    g.height0 = lo.y() - cell;
    g.cols = static_cast<int>((hi.x() - g.along0) / cell) + 2;
    g.rows = static_cast<int>((hi.y() - g.height0) / cell) + 2;
    if (static_cast<long>(g.cols) * g.rows > 4'000'000) return std::nullopt;
    return g;
  }
  size_t size() const { return static_cast<size_t>(cols) * static_cast<size_t>(rows); }
  // The cell of a point (along, height), -1 off the grid.
  int index(const Eigen::Vector2f& q) const {
    const auto col = static_cast<int>(std::floor((q.x() - along0) / cell));
    const auto row = static_cast<int>(std::floor((q.y() - height0) / cell));
    return col >= 0 && col < cols && row >= 0 && row < rows ? row * cols + col : -1;
  }
  // f(d) for the cell c and its 8 neighbours on the grid.
  template <typename F>
  void forNeighbours(int c, const F& f) const {
    const int row = c / cols, col = c % cols;
    for (int r = std::max(0, row - 1); r <= std::min(rows - 1, row + 1); ++r) {
      for (int k = std::max(0, col - 1); k <= std::min(cols - 1, col + 1); ++k) f(r * cols + k);
    }
  }
  // `cells` grown by one cell all round.
  std::vector<uint8_t> grown(const std::vector<uint8_t>& cells) const {
    std::vector<uint8_t> out(cells.size(), 0);
    for (size_t c = 0; c < cells.size(); ++c) {
      if (cells[c]) forNeighbours(static_cast<int>(c), [&](int d) { out[static_cast<size_t>(d)] = 1; });
    }
    return out;
  }
};

// Too few points per occupied cell (fewer than this on average) and a plane's points cannot show
// whether they make a surface or lines: a 50,000-point sample of a fused apartment holds 35
// points per square metre of wall, 1-2 per cell at 15 cm.
constexpr float kMinPointsPerCell = 4.0f;

// The cells of `grid` that hold any of `points` (each: along, height), and whether those on the
// grid are dense enough to show a surface (kMinPointsPerCell).
struct Occupancy {
  std::vector<uint8_t> cells;
  bool dense = false;
};
Occupancy occupancy(const CellGrid& grid, const std::vector<Eigen::Vector2f>& points) {
  Occupancy o;
  o.cells.assign(grid.size(), 0);
  size_t inside = 0, occupied = 0;
  for (const auto& q : points) {
    const int c = grid.index(q);
    if (c < 0) continue;
    ++inside;
    occupied += o.cells[static_cast<size_t>(c)] == 0;
    o.cells[static_cast<size_t>(c)] = 1;
  }
  o.dense = !(static_cast<float>(inside) < kMinPointsPerCell * static_cast<float>(occupied));
  return o;
}

// A wall: the extent of its points on its plane along the floor and up, and where it is a
// connected surface (GravityParams::wall_cell), the cells of the pieces of it that make it a
// wall, grown by one cell all round.
struct Wall {
  Plane plane;
  Eigen::Vector3f along;  // horizontal, in the plane
  float along_lo = 0, along_hi = 0, height_lo = 0, height_hi = 0;
  CellGrid grid;
  std::vector<uint8_t> cells;  // on `grid`; empty: the whole extent
  bool holds(const Eigen::Vector3f& p, const Eigen::Vector3f& up) const {
    constexpr float kMargin = 0.1f;  // a wall's points a little beyond its sampled extent
    const float a = along.dot(p), h = up.dot(p);
    if (a < along_lo - kMargin || a > along_hi + kMargin || h < height_lo - kMargin || h > height_hi + kMargin) return false;
    if (cells.empty()) return true;
    const int c = grid.index({a, h});
    return c >= 0 && cells[static_cast<size_t>(c)] != 0;
  }
};

// The wall of the points `inliers` (each: along, height) on `plane`: their extent (2nd to 98th
// percentile), if it spans a wall's height and width.
std::optional<Wall> extentWall(const Plane& plane, const Eigen::Vector3f& along, const std::vector<Eigen::Vector2f>& inliers,
                               const GravityParams& params) {
  std::vector<float> alongs, heights;
  for (const auto& q : inliers) {
    alongs.push_back(q.x());
    heights.push_back(q.y());
  }
  Wall wall;
  wall.plane = plane;
  wall.along = along;
  wall.along_lo = percentile(alongs, 0.02f);
  wall.along_hi = percentile(alongs, 0.98f);
  wall.height_lo = percentile(heights, 0.02f);
  wall.height_hi = percentile(heights, 0.98f);
  if (wall.height_hi - wall.height_lo < params.wall_min_height || wall.along_hi - wall.along_lo < params.wall_min_width) {
    return std::nullopt;
  }
  return wall;
}

// The wall on `plane` that the points `inliers` (each: along, height) make, if they make one: a
// wall is one connected surface, so its points are joined through the cells they occupy where
// those make a surface (8-neighbours, after opening), and the largest piece must span
// params.wall_min_height and wall_min_width by itself. Points that only share the plane - a
// chair's back, a desk's leg and a shelf's side cut by one vertical plane through a room - span as
// much together but not one by one. The other pieces at least wall_min_height tall are the same
// wall seen around what stands before it. Where the points are too sparse to tell (fewer than
// kMinPointsPerCell per occupied cell), extentWall decides. (Planar regions as connected
// components of a plane's inliers: Trevor, Gedikli, Rusu and Christensen, "Efficient organized
// point cloud segmentation with connected components", 2013; the opening is mathematical
// morphology's, Serra 1982.)
std::optional<Wall> connectedWall(const Plane& plane, const Eigen::Vector3f& along,
                                  const std::vector<Eigen::Vector2f>& inliers, const GravityParams& params) {
  if (inliers.empty()) return std::nullopt;
  if (!(params.wall_cell > 0)) return extentWall(plane, along, inliers, params);
  Eigen::Vector2f lo = inliers[0], hi = inliers[0];
  for (const auto& q : inliers) {
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  const std::optional<CellGrid> grid = CellGrid::around(lo, hi, params.wall_cell);
  if (!grid) return std::nullopt;
  const Occupancy occupied = occupancy(*grid, inliers);
  if (!occupied.dense) return extentWall(plane, along, inliers, params);
  // The occupied cells opened (eroded, then dilated, by a 3 x 3 block): what is left is surface.
  // A plane through a room also cuts other surfaces along lines - a table top's edge, a seat -
  // and those lines join up through cells as a surface does, but hold no 3 x 3 block of them.
  const size_t n = grid->size();
  std::vector<uint8_t> eroded(n, 0);
  for (size_t c = 0; c < n; ++c) {
    if (!occupied.cells[c]) continue;
    int around = 0;
    grid->forNeighbours(static_cast<int>(c), [&](int d) { around += occupied.cells[static_cast<size_t>(d)]; });
    eroded[c] = around == 9;
  }
  const std::vector<uint8_t> opened = grid->grown(eroded);
  std::vector<int> piece(n, -2);  // -2 not surface, -1 not yet joined to a piece
  for (size_t c = 0; c < n; ++c) {
    if (opened[c]) piece[c] = -1;
  }
  struct Extent {
    Eigen::Vector2f lo, hi;
    size_t points = 0;
  };
  std::vector<Extent> extents;
  std::vector<int> stack;
  for (size_t start = 0; start < piece.size(); ++start) {
    if (piece[start] != -1) continue;
    const int id = static_cast<int>(extents.size());
    extents.push_back({Eigen::Vector2f::Constant(INFINITY), Eigen::Vector2f::Constant(-INFINITY), 0});
    piece[start] = id;
    stack.assign(1, static_cast<int>(start));
    while (!stack.empty()) {
      const int c = stack.back();
      stack.pop_back();
      grid->forNeighbours(c, [&](int d) {
        int& next = piece[static_cast<size_t>(d)];
        if (next != -1) return;
        next = id;
        stack.push_back(d);
      });
    }
  }
  if (extents.empty()) return std::nullopt;
  for (const auto& q : inliers) {
    const int id = piece[static_cast<size_t>(grid->index(q))];
    if (id < 0) continue;
    Extent& e = extents[static_cast<size_t>(id)];
    e.lo = e.lo.cwiseMin(q);
    e.hi = e.hi.cwiseMax(q);
    ++e.points;
  }
  const auto largest = std::max_element(extents.begin(), extents.end(),
                                        [](const Extent& a, const Extent& b) { return a.points < b.points; });
  const Eigen::Vector2f span = largest->hi - largest->lo;
  if (span.y() < params.wall_min_height || span.x() < params.wall_min_width) return std::nullopt;
  Wall wall;
  wall.plane = plane;
  wall.along = along;
  wall.grid = *grid;
  std::vector<uint8_t> kept(extents.size(), 0);
  wall.along_lo = wall.height_lo = INFINITY;
  wall.along_hi = wall.height_hi = -INFINITY;
  for (size_t i = 0; i < extents.size(); ++i) {
    kept[i] = &extents[i] == &*largest || extents[i].hi.y() - extents[i].lo.y() >= params.wall_min_height;
    if (!kept[i]) continue;
    // As far as the cells grown from its pieces reach: the cells decide.
    wall.along_lo = std::min(wall.along_lo, extents[i].lo.x() - 2 * grid->cell);
    wall.along_hi = std::max(wall.along_hi, extents[i].hi.x() + 2 * grid->cell);
    wall.height_lo = std::min(wall.height_lo, extents[i].lo.y() - 2 * grid->cell);
    wall.height_hi = std::max(wall.height_hi, extents[i].hi.y() + 2 * grid->cell);
  }
  std::vector<uint8_t> in_kept_piece(n, 0);
  for (size_t c = 0; c < n; ++c) in_kept_piece[c] = piece[c] >= 0 && kept[static_cast<size_t>(piece[c])];
  wall.cells = grid->grown(in_kept_piece);
  return wall;
}

// How far behind a wall's plane a point may lie and still belong to the wall: skirting boards,
// radiators and the sensor's noise a few metres away.
constexpr float kBehindMargin = 0.2f;
// The cells (m, along the floor and up) in which a wall's own points show where it stands: the
// smallest of these in which they lie kMinPointsPerCell to an occupied cell on average, so that
// a dense depth frame resolves a chair's back and a sparse sample of a fused room still shows a
// wall as one surface.
constexpr float kSeenThroughCells[] = {0.05f, 0.1f, 0.15f, 0.2f, 0.3f, 0.4f};

// The points of `room` (the scene above the floor) that lie more than kBehindMargin behind
// `wall`'s plane as seen from `sensor`, within the wall's extent, where its own points (`inliers`:
// along, height) leave a gap of more than a cell: what the sensor saw through the plane. A wall is
// opaque and bounds the room, so a camera sees next to nothing through it (a map, whose
// viewpoint is made up, is not tested: frontend.cc); a plane that only cuts through furniture - a
// chair's back, a desk's front and a cabinet's side in line (tum_desk) - has the rest of the room
// in view behind it. Points behind the wall where its own points stand do not count: a fused
// apartment's next room lies behind its walls. (The free-space argument of Aldoma et al.'s
// hypothesis verification, 2012, applied to a plane.)
size_t seenThrough(const Wall& wall, const std::vector<Eigen::Vector2f>& inliers, const std::vector<Eigen::Vector3f>& room,
                   const Eigen::Vector3f& up, const Eigen::Vector3f& sensor) {
  const Eigen::Vector2f lo(wall.along_lo, wall.height_lo), hi(wall.along_hi, wall.height_hi);
  std::optional<CellGrid> grid;
  Occupancy occupied;
  for (const float size : kSeenThroughCells) {
    std::optional<CellGrid> sized = CellGrid::around(lo, hi, size);
    if (!sized) continue;
    grid = sized;
    occupied = occupancy(*grid, inliers);
    if (occupied.dense) break;
  }
  if (!grid) return 0;
  // The wall's cells, grown by one: a sample leaves single cells of a surface empty.
  const std::vector<uint8_t> covered = grid->grown(occupied.cells);
  const float towards_sensor = wall.plane.distance(sensor) >= 0 ? 1.0f : -1.0f;
  size_t seen = 0;
  for (const auto& p : room) {
    if (towards_sensor * wall.plane.distance(p) >= -kBehindMargin) continue;
    const Eigen::Vector2f q(wall.along.dot(p), up.dot(p));
    if (q.x() < lo.x() || q.x() > hi.x() || q.y() < lo.y() || q.y() > hi.y()) continue;
    const int c = grid->index(q);
    seen += c >= 0 && !covered[static_cast<size_t>(c)];
  }
  return seen;
}

// Walls: vertical planes (through two points and up) with most support whose points make a
// connected surface of a wall's height and width (connectedWall). A large vertical face that is
// not a wall (a wardrobe is, for the purpose) is set aside and the search goes on, as is one seen
// through (seenThrough, where params.wall_max_seen_through is set; `room`: then every point above
// the floor, which `free` starts as).
std::vector<Wall> findWalls(std::vector<Eigen::Vector3f> free, const std::vector<Eigen::Vector3f>& room,
                            const Eigen::Vector3f& up, const Tolerance& tolerance, const GravityParams& params) {
  const Eigen::Vector3f& sensor = tolerance.sensor;
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
    std::vector<Eigen::Vector2f> inliers;
    std::vector<Eigen::Vector3f> rest;
    for (const auto& p : free) {
      const float d = std::abs(plane.distance(p));
      if (d <= params.inlier_distance) inliers.emplace_back(along.dot(p), up.dot(p));
      if (d > tolerance(p)) rest.push_back(p);
    }
    auto wall = connectedWall(plane, along, inliers, params);
    if (wall && params.wall_max_seen_through > 0 &&
        static_cast<float>(seenThrough(*wall, inliers, room, up, sensor)) >
            params.wall_max_seen_through * static_cast<float>(inliers.size())) {
      wall.reset();
    }
    if (wall) walls.push_back(std::move(*wall));
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
  std::optional<Floor> floor = findFloor(sample, g.up, radians(given_up ? params.given_up_tolerance_deg : params.max_tilt_deg),
                                         given_up.has_value(), params);
  bool up_from_floor = !given_up && floor.has_value();
  if (given_up && params.given_up_kept_deg < params.given_up_tolerance_deg) {
    // The given up checked against the floor: planes within the tolerance of it, not only square
    // to it. A floor that holds more points than the one square to the given up, and whose normal
    // is more than given_up_kept_deg from it, shows the caller's frame to be tilted.
    std::optional<Floor> tilted = findFloor(sample, g.up, radians(params.given_up_tolerance_deg), false, params);
    if (tilted && (!floor || tilted->support > floor->support) &&
        tilted->plane.normal.dot(g.up) < std::cos(radians(params.given_up_kept_deg))) {
      floor = tilted;
      up_from_floor = true;
    }
  }
  if (floor) {
    if (up_from_floor) {
      g.up = floor->plane.normal;
      g.source = UpSource::kFloor;
    }
    g.floor_level = floor->plane.offset;
  }

  const Tolerance tolerance{sensor_origin, params};
  std::vector<Eigen::Vector3f> free;
  for (const auto& p : sample) {
    if (!g.hasFloor() || g.height(p) > tolerance(p)) free.push_back(p);
  }
  std::vector<Eigen::Vector3f> room;
  if (params.wall_max_seen_through > 0) room = free;
  const std::vector<Wall> walls = findWalls(std::move(free), room, g.up, tolerance, params);
  g.walls = static_cast<int>(walls.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    const float tol = tolerance(p);
    if (g.hasFloor() && std::abs(g.height(p)) <= tol) {
      result.labels[i] = PlaneLabel::kFloor;
      ++g.floor_points;
      continue;
    }
    for (const Wall& w : walls) {
      if (std::abs(w.plane.distance(p)) > tol || !w.holds(p, g.up)) continue;
      result.labels[i] = PlaneLabel::kWall;
      ++g.wall_points;
      break;
    }
  }
  return result;
}

}  // namespace ism
