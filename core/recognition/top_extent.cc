#include "core/recognition/top_extent.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Eigenvalues>

#include "core/common/upright_box.h"

namespace ism {
namespace {

constexpr float kBin = 0.02f;  // the top's height is sought in layers this thick (m)

// A square grid of cells over the gravity frame's x and y, flags per cell. Its window holds every
// set cell; morphology looks only there.
class Grid {
 public:
  Grid(Eigen::Vector2f min, float cell, int n)
      : min_(min), cell_(cell), n_(n), lo_(0, 0), hi_(n - 1, n - 1), flags_(static_cast<size_t>(n) * static_cast<size_t>(n), 0) {}
  bool cellOf(const Eigen::Vector2f& p, int& x, int& y) const {
    const Eigen::Vector2f f = (p - min_) / cell_;
    if (!(f.x() >= 0 && f.y() >= 0)) return false;
    x = static_cast<int>(f.x()), y = static_cast<int>(f.y());
    return x < n_ && y < n_;
  }
  Eigen::Vector2f centre(int x, int y) const {
    return min_ + cell_ * Eigen::Vector2f(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f);
  }
  bool at(int x, int y) const { return x >= 0 && y >= 0 && x < n_ && y < n_ && flags_[index(x, y)] != 0; }
  void set(int x, int y, bool v = true) { flags_[index(x, y)] = v ? 1 : 0; }
  // The window: the set cells' bounding rectangle grown by `margin` cells, within the grid. A
  // closing sets no cell outside the rectangle (the erosion clears each cell the dilation added
  // there, as its neighbours farther out stay clear), and the opening's dilation reaches one cell
  // past it, so the top's morphology needs a margin of 1. Empty (lo > hi) when no cell is set.
  void fitWindow(int margin) {
    Eigen::Vector2i lo(n_, n_), hi(-1, -1);
    for (int y = 0; y < n_; ++y) {
      for (int x = 0; x < n_; ++x) {
        if (flags_[index(x, y)] == 0) continue;
        lo = lo.cwiseMin(Eigen::Vector2i(x, y));
        hi = hi.cwiseMax(Eigen::Vector2i(x, y));
      }
    }
    if (hi.x() < 0) {
      lo_ = {0, 0}, hi_ = {-1, -1};
      return;
    }
    lo_ = (lo.array() - margin).max(0).matrix();
    hi_ = (hi.array() + margin).min(n_ - 1).matrix();
  }
  const Eigen::Vector2i& lo() const { return lo_; }
  const Eigen::Vector2i& hi() const { return hi_; }

  // Morphology with the 3 x 3 square; outside the grid is empty.
  Grid dilated() const { return morph(false); }
  Grid eroded() const { return morph(true); }
  Grid operator&(const Grid& other) const {
    Grid out = *this;
    for (size_t i = 0; i < flags_.size(); ++i) out.flags_[i] = flags_[i] & other.flags_[i];
    return out;
  }

 private:
  size_t index(int x, int y) const { return static_cast<size_t>(y) * static_cast<size_t>(n_) + static_cast<size_t>(x); }
  Grid morph(bool all) const {
    Grid out(min_, cell_, n_);
    out.lo_ = lo_, out.hi_ = hi_;
    for (int y = lo_.y(); y <= hi_.y(); ++y) {
      for (int x = lo_.x(); x <= hi_.x(); ++x) {
        bool v = all;
        for (int dy = -1; dy <= 1 && v == all; ++dy) {
          for (int dx = -1; dx <= 1 && v == all; ++dx) {
            if (at(x + dx, y + dy) != all) v = !all;
          }
        }
        out.set(x, y, v);
      }
    }
    return out;
  }
  Eigen::Vector2f min_;
  float cell_;
  int n_;
  Eigen::Vector2i lo_, hi_;  // the window, corners included
  std::vector<uint8_t> flags_;
};

// The smallest of the rectangles about `points` whose axes follow one of `yaws`: its centre, its
// sides along its own x and y, and its yaw.
void tightestRectangle(const std::vector<Eigen::Vector2f>& points, const std::vector<float>& yaws,
                       Eigen::Vector2f& centre, Eigen::Vector2f& sides, float& yaw) {
  float best = std::numeric_limits<float>::infinity();
  for (const float candidate : yaws) {
    const float c = std::cos(candidate), s = std::sin(candidate);
    Eigen::Vector2f lo = Eigen::Vector2f::Constant(std::numeric_limits<float>::infinity()), hi = -lo;
    for (const auto& p : points) {
      const Eigen::Vector2f local(c * p.x() + s * p.y(), -s * p.x() + c * p.y());
      lo = lo.cwiseMin(local);
      hi = hi.cwiseMax(local);
    }
    const Eigen::Vector2f size = hi - lo;
    if (size.prod() >= best) continue;
    best = size.prod();
    const Eigen::Vector2f mid = (lo + hi) / 2;
    centre = {c * mid.x() - s * mid.y(), s * mid.x() + c * mid.y()};
    sides = size;
    yaw = candidate;
  }
}

}  // namespace

bool flatTopped(const CategoryModel& category, const TopExtentParams& params) {
  int shapes = 0, flat = 0;
  for (const auto& o : category.objects) {
    if (o.surface.empty()) continue;
    float top = -std::numeric_limits<float>::infinity();
    for (const auto& p : o.surface) top = std::max(top, p.z());
    const auto near_top = std::count_if(o.surface.begin(), o.surface.end(),
                                        [&](const Eigen::Vector3f& p) { return p.z() >= top - params.layer; });
    ++shapes;
    if (static_cast<float>(near_top) >= params.min_top_share * static_cast<float>(o.surface.size())) ++flat;
  }
  return shapes > 0 && 2 * flat > shapes;
}

bool withinFootprintPrior(const Hypothesis& hypothesis, const CategoryModel& category, const Eigen::Matrix3f& to_gravity,
                          float slack) {
  const auto narrow = [](const Eigen::Vector3f& size) { return size.head<2>().minCoeff(); };
  // Only the objects whose size was given. A mesh without one is scaled to the box that best fits
  // its category's typical size, which pulls every such table's narrow side towards the typical
  // one (the seed's three PSB tables came out 0.80-0.91 m deep), so their range tells the typical
  // size back, not the sizes tables come in, and a square test table of the same collection fell
  // outside it (docs/EVALUATION.md, "The seed's baseline on synthetic scans").
  return withinTrainingRange(category, [&](const TrainingObject& o) { return narrow(o.size); },
                             narrow(uprightBoxOf(hypothesis.box, to_gravity).size), slack,
                             [](const TrainingObject& o) { return !o.size_guessed; });
}

bool withinHeightPrior(const Hypothesis& hypothesis, const CategoryModel& category, const Eigen::Matrix3f& to_gravity,
                       float slack) {
  return withinTrainingRange(category, [](const TrainingObject& o) { return o.size.z(); },
                             uprightBoxOf(hypothesis.box, to_gravity).size.z(), slack,
                             [](const TrainingObject& o) { return !o.size_guessed; });
}

TopFound extendToTop(const VerificationScene& scene, Hypothesis& hypothesis, const TopExtentParams& params) {
  if (!params.enabled || !hypothesis.upright_box || !hypothesis.verification) return TopFound::kNotLooked;
  const SceneBox local = sceneBox(scene, hypothesis);
  const UprightBox& box = local.box;
  const Eigen::Vector3f sensor = scene.to_gravity * scene.origin;
  const Eigen::Vector3f& centre = box.center;  // scene.points' frame
  const float bottom = local.floor_z;
  const float fitted_top = local.top();
  const auto in_footprint = [&](const Eigen::Vector3f& p) { return local.overFootprint(p); };

  // The top's height: the densest thin layer over the fitted footprint near the fitted top.
  const float from = fitted_top - params.below;
  std::vector<int> layers(static_cast<size_t>(std::ceil((params.below + params.above) / kBin)), 0);
  for (const auto& p : scene.points) {
    const float z = p.z() - from;
    if (z < 0 || z >= static_cast<float>(layers.size()) * kBin || !in_footprint(p)) continue;
    ++layers[std::min(layers.size() - 1, static_cast<size_t>(z / kBin))];
  }
  const auto densest = std::max_element(layers.begin(), layers.end());
  if (*densest < params.min_points) return TopFound::kMissing;
  const float top = from + (static_cast<float>(densest - layers.begin()) + 0.5f) * kBin;
  if (top <= bottom + 2 * params.layer) return TopFound::kMissing;

  // The measured points at that height, on a grid about the fitted box.
  const int n = std::max(3, static_cast<int>(std::ceil(params.max_side / params.cell)));
  const float half = 0.5f * params.cell * static_cast<float>(n);
  Grid measured(centre.head<2>() - Eigen::Vector2f::Constant(half), params.cell, n);
  std::vector<Eigen::Vector2f> layer;
  for (const auto& p : scene.points) {
    int x = 0, y = 0;
    if (std::abs(p.z() - top) > params.layer || !measured.cellOf(p.head<2>(), x, y)) continue;
    measured.set(x, y);
    layer.push_back(p.head<2>());
  }
  // Closed over a sample's holes, then opened: a part one or two cells thin at this height (a
  // backrest, a wall, a monitor's foot) does not join the top to what stands beside it.
  measured.fitWindow(1);
  const Grid closed = measured.dilated().eroded();
  const Grid opened = closed.eroded().dilated() & closed;

  // The cells of the top's height the sensor cannot see: a measured point at least kInFront nearer
  // to the sensor (the origin) lies on the line of sight to them. The sensor stands well off the
  // top's height, else every line of sight grazes it.
  constexpr float kInFront = 0.1f;
  const int max_run = scene.map || !(params.max_hidden_run > 0)
                          ? 0
                          : static_cast<int>(std::min(std::floor(params.max_hidden_run / params.cell), static_cast<float>(n)));
  Grid hidden(centre.head<2>() - Eigen::Vector2f::Constant(half), params.cell, n);
  if (max_run > 0 && std::abs(top) > kInFront) {
    for (const auto& p : scene.points) {
      const float t = p.z() / top;  // p lies on the line of sight to p / t, at the top's height
      if (!(t > 0 && t < 1) || (1 - t) * p.norm() < kInFront * t) continue;
      int x = 0, y = 0;
      if (hidden.cellOf(p.head<2>() / t, x, y)) hidden.set(x, y);
    }
    hidden.fitWindow(1);
    hidden = hidden.dilated().eroded();  // the sample's gaps, magnified on their way to the top
  }

  // Grown from the cells within the fitted footprint: through the top's cells, and through runs of
  // at most max_run cells hidden, or thin at its height (the back that hides them), between them.
  Grid reached(centre.head<2>() - Eigen::Vector2f::Constant(half), params.cell, n);
  std::vector<int16_t> left(static_cast<size_t>(n) * static_cast<size_t>(n), -1);  // the run left on arrival
  const auto at_index = [n](int x, int y) { return static_cast<size_t>(y) * static_cast<size_t>(n) + static_cast<size_t>(x); };
  std::vector<std::pair<int, int>> frontier;
  for (int y = opened.lo().y(); y <= opened.hi().y(); ++y) {  // no cell outside the window is set
    for (int x = opened.lo().x(); x <= opened.hi().x(); ++x) {
      const Eigen::Vector2f at = opened.centre(x, y);
      if (opened.at(x, y) && in_footprint({at.x(), at.y(), top})) {
        reached.set(x, y);
        left[at_index(x, y)] = static_cast<int16_t>(max_run);
        frontier.emplace_back(x, y);
      }
    }
  }
  if (frontier.empty()) return TopFound::kMissing;
  while (!frontier.empty()) {
    const auto [x, y] = frontier.back();
    frontier.pop_back();
    const int run = left[at_index(x, y)];
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = x + dx, ny = y + dy;
        if (nx < 0 || ny < 0 || nx >= n || ny >= n) continue;
        int next = -1;
        if (opened.at(nx, ny)) {
          next = max_run;
        } else if (run > 0 && (hidden.at(nx, ny) || closed.at(nx, ny))) {
          next = run - 1;
        }
        if (next <= left[at_index(nx, ny)]) continue;
        left[at_index(nx, ny)] = static_cast<int16_t>(next);
        if (opened.at(nx, ny)) reached.set(nx, ny);
        frontier.emplace_back(nx, ny);
      }
    }
  }

  // The measured points of the top (not its cells, which would add up to a cell on each side),
  // boxed along the fitted heading or their own main axis, whichever is tighter.
  std::vector<Eigen::Vector2f> top_points;
  for (const auto& p : layer) {
    int x = 0, y = 0;
    if (reached.cellOf(p, x, y) && reached.at(x, y)) top_points.push_back(p);
  }
  if (top_points.empty()) return TopFound::kMissing;
  std::vector<float> yaws{box.yaw};
  if (top_points.size() >= 3) {
    Eigen::Vector2f mean = Eigen::Vector2f::Zero();
    for (const auto& p : top_points) mean += p;
    mean /= static_cast<float>(top_points.size());
    Eigen::Matrix2f covariance = Eigen::Matrix2f::Zero();
    for (const auto& p : top_points) covariance += (p - mean) * (p - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2f> solver(covariance);
    const Eigen::Vector2f axis = solver.eigenvectors().col(1);  // largest eigenvalue last
    yaws.push_back(std::atan2(axis.y(), axis.x()));
  }
  Eigen::Vector2f middle, sides;
  float yaw = box.yaw;
  tightestRectangle(top_points, yaws, middle, sides, yaw);
  // Samples of a surface stop short of its edges by about half their spacing.
  const float spacing = std::sqrt(sides.prod() / static_cast<float>(top_points.size()));
  sides += Eigen::Vector2f::Constant(spacing);
  UprightBox extent;
  extent.center = Eigen::Vector3f(middle.x(), middle.y(), (bottom + top) / 2) + sensor;
  extent.size = {sides.x(), sides.y(), top - bottom};
  extent.yaw = yaw;
  hypothesis.box = extent.toScene(scene.to_gravity);
  return TopFound::kFound;
}

}  // namespace ism
