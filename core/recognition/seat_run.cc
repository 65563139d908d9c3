#include "core/recognition/seat_run.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace ism {

float seatRun(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector2f& centre, const Eigen::Vector2f& axis,
              float half_width, float floor_z, const SeatRunParams& params) {
  // Cells [-half, half) along the axis; cell `half` holds [0, cell), `half - 1` holds [-cell, 0).
  const int half = std::max(1, static_cast<int>(std::ceil(params.reach / params.cell)));
  std::vector<char> occupied(static_cast<size_t>(2 * half), 0);
  const Eigen::Vector2f across(-axis.y(), axis.x());
  for (const auto& p : points) {
    const float height = p.z() - floor_z;
    if (height < params.from || height > params.to) continue;
    const Eigen::Vector2f d = p.head<2>() - centre;
    if (std::abs(d.dot(across)) > half_width) continue;
    const float along = std::floor(d.dot(axis) / params.cell);
    if (along < static_cast<float>(-half) || along >= static_cast<float>(half)) continue;
    occupied[static_cast<size_t>(static_cast<int>(along) + half)] = 1;
  }
  const auto at = [&](int k) { return k >= 0 && k < 2 * half && occupied[static_cast<size_t>(k)] != 0; };
  if (!at(half) && !at(half - 1)) return 0.0f;
  int lo = at(half) ? half : half - 1;
  int hi = lo;
  for (int k = hi + 1, gap = 0; k < 2 * half; ++k) {
    if (at(k)) {
      hi = k, gap = 0;
    } else if (++gap > params.max_gap) {
      break;
    }
  }
  for (int k = lo - 1, gap = 0; k >= 0; --k) {
    if (at(k)) {
      lo = k, gap = 0;
    } else if (++gap > params.max_gap) {
      break;
    }
  }
  return static_cast<float>(hi - lo + 1) * params.cell;
}

namespace {

// The unit vector along a box's longer horizontal side, given its yaw, and the half of the other.
std::pair<Eigen::Vector2f, float> longSide(const Eigen::Vector3f& size, float yaw) {
  const Eigen::Vector2f x(std::cos(yaw), std::sin(yaw));
  if (size.x() >= size.y()) return {x, size.y() / 2};
  return {Eigen::Vector2f(-x.y(), x.x()), size.x() / 2};
}

}  // namespace

std::optional<float> trainingSeatRun(const CategoryModel& category, const SeatRunParams& params) {
  std::optional<float> shortest;
  for (const auto& o : category.objects) {
    if (o.surface.empty()) continue;  // a shape calibration holds out
    const auto [axis, half_width] = longSide(o.size, 0.0f);
    const float run = seatRun(o.surface, Eigen::Vector2f::Zero(), axis, half_width, 0.0f, params);
    shortest = std::min(shortest.value_or(std::numeric_limits<float>::infinity()), run);
  }
  return shortest;
}

SeatRunCheck checkSeatRun(const VerificationScene& scene, const Hypothesis& hypothesis,
                          const std::optional<float>& training_run, const SeatRunParams& params) {
  SeatRunCheck check;
  if (!params.enabled || !training_run || !hypothesis.upright_box || !hypothesis.verification) return check;
  const SceneBox local = sceneBox(scene, hypothesis);
  const auto [axis, half_width] = longSide(local.box.size, local.box.yaw);
  check.looked = true;
  check.run = seatRun(scene.points, local.box.center.head<2>(), axis, half_width, local.floor_z, params);
  check.required = params.min_share * *training_run;
  return check;
}

}  // namespace ism
