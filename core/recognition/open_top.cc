#include "core/recognition/open_top.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <vector>

namespace ism {

namespace {

// Adds `p` (VerificationScene::points' frame) to `beside` in the box's frame when it lies in reach
// of the run-on strips at a height they look at.
void addBeside(const SceneBox& local, const Eigen::Vector3f& p, const OpenTopParams& params,
               std::vector<Eigen::Vector3f>& beside) {
  const Eigen::Vector3f q = local.boxFrame(p);
  if (q.z() <= params.run_from || q.z() >= std::max(params.run_to, params.run_level_cap)) return;
  if (std::abs(q.x()) < local.box.size.x() / 2 + params.run_far &&
      std::abs(q.y()) < local.box.size.y() / 2 + params.run_far) {
    beside.push_back(q);
  }
}

// Each of the four strips' share of cells filled by a point in the seat's band, and of cells whose
// highest point below the cap lies within one level band up to run_level_to (runOnShare).
struct StripShares {
  std::array<float, 4> seat{}, level{};
};

StripShares stripShares(const std::vector<Eigen::Vector3f>& points, float width, float depth,
                        const OpenTopParams& params) {
  const float cell = std::max(params.run_cell, 1e-3f);
  const int across = std::max(1, static_cast<int>((params.run_far - params.run_near) / cell));
  // Strips 0 and 1 lie beyond the ends of the width (x), 2 and 3 beyond those of the depth (y);
  // each runs along the middle `inner` of its side.
  const float side[2] = {params.inner * depth, params.inner * width};
  const int along[2] = {std::max(1, static_cast<int>(side[0] / cell)), std::max(1, static_cast<int>(side[1] / cell))};
  const bool level = params.run_level_to > params.run_from;
  constexpr float kNone = -std::numeric_limits<float>::infinity();
  std::vector<uint8_t> filled[4];
  std::vector<float> highest[4];
  for (int s = 0; s < 4; ++s) {
    filled[s].assign(static_cast<size_t>(along[s / 2] * across), 0);
    highest[s].assign(filled[s].size(), kNone);
  }
  for (const auto& p : points) {
    const bool seat = p.z() > params.run_from && p.z() < params.run_to;
    const bool below_cap = level && p.z() > params.run_from && p.z() < params.run_level_cap;
    if (!seat && !below_cap) continue;
    for (int s = 0; s < 4; ++s) {
      const int axis = s / 2;
      const float sign = s % 2 == 0 ? 1.0f : -1.0f;
      const float out = sign * (axis == 0 ? p.x() : p.y()) - (axis == 0 ? width : depth) / 2;
      const float at = (axis == 0 ? p.y() : p.x()) + side[axis] / 2;
      if (!(out >= params.run_near && out < params.run_far && at >= 0 && at < side[axis])) continue;  // NaN too
      const int u = std::min(along[axis] - 1, static_cast<int>(at / side[axis] * static_cast<float>(along[axis])));
      const int v = std::min(across - 1, static_cast<int>((out - params.run_near) / cell));
      const auto c = static_cast<size_t>(u * across + v);
      if (seat) filled[s][c] = 1;
      if (below_cap) highest[s][c] = std::max(highest[s][c], p.z());
    }
  }
  StripShares shares;
  for (int s = 0; s < 4; ++s) {
    const auto cells = static_cast<float>(filled[s].size());
    shares.seat[s] = static_cast<float>(std::count(filled[s].begin(), filled[s].end(), uint8_t{1})) / cells;
    if (!level) continue;
    std::vector<float> tops;  // the cells whose highest point is a surface up to run_level_to
    for (const float h : highest[s]) {
      if (std::isfinite(h) && h < params.run_level_to) tops.push_back(h);
    }
    std::sort(tops.begin(), tops.end());
    size_t in_band = 0;
    for (size_t lo = 0, hi = 0; hi < tops.size(); ++hi) {
      while (tops[hi] - tops[lo] >= params.level_band) ++lo;
      in_band = std::max(in_band, hi - lo + 1);
    }
    shares.level[s] = static_cast<float>(in_band) / cells;
  }
  return shares;
}

// The points in the top of the body's band over the footprint, per cell, and the cells holding
// surface over the top (OpenTopParams::upper_clearance).
class UpperCells {
 public:
  UpperCells(const SceneBox& local, const OpenTopParams& params)
      : params_(params),
        cell_(std::max(params.upper_cell, 1e-3f)),
        width_(local.box.size.x()),
        depth_(local.box.size.y()),
        nx_(std::max(1, static_cast<int>(std::ceil(width_ / cell_)))),
        ny_(std::max(1, static_cast<int>(std::ceil(depth_ / cell_)))),
        in_band_(static_cast<size_t>(nx_ * ny_), 0),
        over_top_(in_band_.size(), 0) {}

  // `q` in the box's frame (SceneBox::boxFrame), over the footprint; `over_top`: whether it lies
  // where the open top counts surface over the top.
  void add(const Eigen::Vector3f& q, bool over_top) {
    const bool band = q.z() > params_.upper_from && q.z() < params_.upper_to;
    if (!band && !over_top) return;
    const int ix = std::clamp(static_cast<int>((q.x() + width_ / 2) / cell_), 0, nx_ - 1);
    const int iy = std::clamp(static_cast<int>((q.y() + depth_ / 2) / cell_), 0, ny_ - 1);
    const auto c = static_cast<size_t>(iy * nx_ + ix);
    if (band) ++in_band_[c];
    if (over_top) over_top_[c] = 1;
  }

  // The band's points in cells clear of every cell with surface over the top.
  int clear() const {
    if (params_.upper_clearance <= 0) return std::accumulate(in_band_.begin(), in_band_.end(), 0);
    const int reach = static_cast<int>(std::lround(params_.upper_clearance / cell_));
    int points = 0;
    for (int y = 0; y < ny_; ++y) {
      for (int x = 0; x < nx_; ++x) {
        const int in_band = in_band_[static_cast<size_t>(y * nx_ + x)];
        if (in_band > 0 && clearOfTop(x, y, reach)) points += in_band;
      }
    }
    return points;
  }

 private:
  bool clearOfTop(int x, int y, int reach) const {
    for (int v = std::max(0, y - reach); v <= std::min(ny_ - 1, y + reach); ++v) {
      for (int u = std::max(0, x - reach); u <= std::min(nx_ - 1, x + reach); ++u) {
        if (over_top_[static_cast<size_t>(v * nx_ + u)]) return false;
      }
    }
    return true;
  }

  const OpenTopParams& params_;
  float cell_, width_, depth_;
  int nx_, ny_;
  std::vector<int> in_band_;
  std::vector<uint8_t> over_top_;
};

}  // namespace

OpenTopCheck checkOpenTop(const VerificationScene& scene, const Hypothesis& hypothesis, const OpenTopParams& params,
                          const TrainingObject* fitted) {
  OpenTopCheck check;
  if (!params.enabled || !hypothesis.upright_box || !hypothesis.verification) return check;
  const SceneBox local = sceneBox(scene, hypothesis);
  const float top = local.top();
  check.looked = true;
  check.max_share = params.max_share;
  check.min_upper = params.min_upper;
  check.max_level = params.max_level;
  check.max_run_on = params.max_level > 0 ? params.max_run_on : 0.0f;
  const int back = fitted && params.behind_back && params.max_run_on > 0
                       ? backSide(*fitted, hypothesis.verification->yaw - local.box.yaw)
                       : -1;
  if (back >= 0) check.max_behind = params.max_run_on;
  const int near = params.near_edge > 0 ? sensorSide(scene, local) : -1;
  // The near strip spans the side's inner part, as the open top counts the inner footprint.
  const float near_along = near >= 0 ? params.inner * local.box.size[1 - near / 2] / 2 : 0.0f;
  UpperCells upper(local, params);
  std::vector<Eigen::Vector3f> footprint, beside;  // SceneBox::boxFrame
  for (const auto& p : scene.points) {
    const bool over = local.overFootprint(p);
    if ((check.max_run_on > 0 || back >= 0) && !over) addBeside(local, p, params, beside);
    // The inner part of the footprint lies within it (most of the scene is over neither).
    if (!over && params.inner <= 1) continue;
    const bool over_top = p.z() > top + params.from && p.z() < top + params.to;
    const bool in_body = p.z() - local.floor_z > params.body_from && p.z() < top;
    if (over) {
      const Eigen::Vector3f q = local.boxFrame(p);
      if (near >= 0 && local.inFrom(near, q) < params.near_edge && local.alongSide(near, q) < near_along) {
        if (over_top) {
          ++check.near_above;
        } else if (in_body) {
          ++check.near_body;
        }
      }
      if (params.max_level > 0) footprint.push_back(q);
      upper.add(q, over_top);
    }
    if (!local.overFootprint(p, params.inner)) continue;
    if (over_top) {
      ++check.above;
    } else if (in_body) {
      ++check.body;
    }
  }
  check.upper = upper.clear();
  if (params.max_level > 0) {
    check.level_share = levelShare(footprint, local.box.size.x(), local.box.size.y(), top - local.floor_z, params);
  }
  if (check.max_run_on > 0 || back >= 0) {
    const StripShares shares = stripShares(beside, local.box.size.x(), local.box.size.y(), params);
    for (int s = 0; s < 4 && check.max_run_on > 0; ++s) {
      check.run_on_share = std::max({check.run_on_share, shares.seat[s], shares.level[s]});
    }
    if (back >= 0) check.behind_back_share = shares.level[static_cast<size_t>(back)];
  }
  return check;
}

float runOnShare(const std::vector<Eigen::Vector3f>& points, float width, float depth, const OpenTopParams& params) {
  const StripShares shares = stripShares(points, width, depth, params);
  float most = 0;
  for (int s = 0; s < 4; ++s) most = std::max({most, shares.seat[s], shares.level[s]});
  return most;
}

int backSide(const TrainingObject& object, float yaw) {
  Eigen::Vector2f back = Eigen::Vector2f::Zero();
  for (const auto& q : object.surface) {
    if (q.z() > 0.75f * object.size.z()) back += q.head<2>();
  }
  if (back.norm() < 1e-6f) return -1;
  const float c = std::cos(yaw), s = std::sin(yaw);
  const Eigen::Vector2f turned(c * back.x() - s * back.y(), s * back.x() + c * back.y());
  if (std::abs(turned.x()) > std::abs(turned.y())) return turned.x() > 0 ? 0 : 1;
  return turned.y() > 0 ? 2 : 3;
}

float levelShare(const std::vector<Eigen::Vector3f>& points, float width, float depth, float top,
                 const OpenTopParams& params) {
  const float cell = std::max(params.level_cell, 1e-3f);
  const int nx = std::max(1, static_cast<int>(std::lround(width / cell)));
  const int ny = std::max(1, static_cast<int>(std::lround(depth / cell)));
  constexpr float kNone = -std::numeric_limits<float>::infinity();
  std::vector<float> highest(static_cast<size_t>(nx) * static_cast<size_t>(ny), kNone);
  for (const auto& p : points) {
    if (p.z() <= params.body_from || p.z() >= top + params.level_over) continue;
    const float u = (p.x() + width / 2) / width, v = (p.y() + depth / 2) / depth;
    if (u < 0 || u > 1 || v < 0 || v > 1) continue;
    const int ix = std::min(nx - 1, static_cast<int>(u * static_cast<float>(nx)));
    const int iy = std::min(ny - 1, static_cast<int>(v * static_cast<float>(ny)));
    float& h = highest[static_cast<size_t>(ix) * static_cast<size_t>(ny) + static_cast<size_t>(iy)];
    h = std::max(h, p.z());
  }
  std::vector<float> tops;
  for (const float h : highest) {
    if (std::isfinite(h)) tops.push_back(h);
  }
  std::sort(tops.begin(), tops.end());
  size_t most = 0;
  for (size_t lo = 0, hi = 0; hi < tops.size(); ++hi) {
    while (tops[hi] - tops[lo] >= params.level_band) ++lo;
    most = std::max(most, hi - lo + 1);
  }
  return static_cast<float>(most) / static_cast<float>(highest.size());
}

bool stepTopTrained(const CategoryModel& category, const OpenTopParams& params) {
  if (params.max_level <= 0) return false;
  bool any = false;
  for (const auto& o : category.objects) {
    if (o.surface.empty()) continue;  // a shape calibration holds out
    if (levelShare(o.surface, o.size.x(), o.size.y(), o.size.z(), params) >= params.max_level) return false;
    any = true;
  }
  return any;
}

bool upperPartTrained(const CategoryModel& category, const OpenTopParams& params) {
  if (params.min_upper <= 0) return false;
  bool any = false;
  for (const auto& o : category.objects) {
    if (o.surface.empty()) continue;  // a shape calibration holds out
    const auto upper = std::count_if(o.surface.begin(), o.surface.end(), [&](const Eigen::Vector3f& p) {
      return p.z() > params.upper_from && p.z() < params.upper_to;
    });
    if (upper < params.min_upper) return false;
    any = true;
  }
  return any;
}

}  // namespace ism
