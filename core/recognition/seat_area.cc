#include "core/recognition/seat_area.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace ism {

float seatAreaShare(const std::vector<Eigen::Vector3f>& points, float width, float depth,
                    const SeatAreaParams& params) {
  const float w = params.inner * width, d = params.inner * depth;
  if (w <= 0 || d <= 0) return 0;
  const int nx = std::max(1, static_cast<int>(std::ceil(w / params.cell)));
  const int ny = std::max(1, static_cast<int>(std::ceil(d / params.cell)));
  std::vector<char> seat(static_cast<size_t>(nx) * static_cast<size_t>(ny), 0);
  for (const auto& p : points) {
    if (p.z() < params.from || p.z() > params.to) continue;
    const float u = (p.x() + w / 2) / w, v = (p.y() + d / 2) / d;
    if (u < 0 || u >= 1 || v < 0 || v >= 1) continue;
    seat[static_cast<size_t>(u * static_cast<float>(nx)) * static_cast<size_t>(ny) +
         static_cast<size_t>(v * static_cast<float>(ny))] = 1;
  }
  return static_cast<float>(std::count(seat.begin(), seat.end(), 1)) / static_cast<float>(seat.size());
}

bool seatAreaTrained(const CategoryModel& category, const SeatAreaParams& params) {
  if (!params.enabled) return false;
  bool any = false;
  for (const auto& o : category.objects) {
    if (o.surface.empty()) continue;  // a shape calibration holds out
    // The shape's surface is about its box's centre, standing on z = 0.
    if (seatAreaShare(o.surface, o.size.x(), o.size.y(), params) < params.min_share) return false;
    any = true;
  }
  return any;
}

SeatAreaCheck checkSeatArea(const VerificationScene& scene, const Hypothesis& hypothesis, bool trained,
                            const SeatAreaParams& params) {
  SeatAreaCheck check;
  if (!params.enabled || !trained || !hypothesis.upright_box || !hypothesis.verification) return check;
  const SceneBox local = sceneBox(scene, hypothesis);
  check.looked = true;
  check.min_share = params.min_share;
  std::vector<Eigen::Vector3f> seat;  // only what can count, in the box's frame above the floor
  for (const auto& p : scene.points) {
    const Eigen::Vector3f q = local.boxFrame(p);
    if (q.z() >= params.from && q.z() <= params.to) seat.push_back(q);
  }
  check.share = seatAreaShare(seat, local.box.size.x(), local.box.size.y(), params);
  return check;
}

}  // namespace ism
