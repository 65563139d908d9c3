#include "core/recognition/seat_area.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/recognition/footprint_cells.h"

namespace ism {
namespace {

// The cells holding a point at seat height.
std::vector<char> seatCells(const std::vector<Eigen::Vector3f>& points, const FootprintCells& cells,
                            const SeatAreaParams& params) {
  std::vector<char> seat(cells.size(), 0);
  for (const auto& p : points) {
    if (p.z() < params.from || p.z() > params.to) continue;
    const int i = cells.of(p.x(), p.y());
    if (i >= 0) seat[static_cast<size_t>(i)] = 1;
  }
  return seat;
}

constexpr float kNearest = 0.3f;  // m along the view

// Which cells a single view's sensor (at the origin of scene.points) saw at seat height: the scene
// is projected on a plane facing the footprint, and each direction keeps the nearest measured
// depth; a cell's middle at seat height is seen when that depth is not nearer than its own by
// more than the margin. A direction with nothing measured says nothing.
std::vector<char> seenCells(const VerificationScene& scene, const SceneBox& local, const FootprintCells& cells,
                            const SeatAreaParams& params) {
  std::vector<char> seen(cells.size(), 0);
  const float seat_height = (params.from + params.to) / 2;
  const Eigen::Vector3f centre = local.sceneFrame({0.0f, 0.0f, seat_height});
  if (centre.norm() < 1e-3f) return seen;
  const Eigen::Vector3f forward = centre.normalized();
  Eigen::Vector3f right = forward.cross(Eigen::Vector3f::UnitZ());
  if (right.norm() < 1e-3f) right = forward.cross(Eigen::Vector3f::UnitX());  // straight down at it
  right.normalize();
  const Eigen::Vector3f up = right.cross(forward);
  struct Probe {
    float a, b, depth;
  };
  std::vector<Probe> probes(cells.size());
  float a0 = std::numeric_limits<float>::max(), a1 = -a0, b0 = a0, b1 = -a0;
  for (size_t i = 0; i < cells.size(); ++i) {
    const Eigen::Vector2f m = cells.middle(static_cast<int>(i));
    const Eigen::Vector3f p = local.sceneFrame({m.x(), m.y(), seat_height});
    const float t = p.dot(forward);
    // The sensor over or next to the footprint: too near to tell (and the directions' bins would
    // spread without bound).
    if (t <= kNearest) return seen;
    probes[i] = {p.dot(right) / t, p.dot(up) / t, t};
    a0 = std::min(a0, probes[i].a), a1 = std::max(a1, probes[i].a);
    b0 = std::min(b0, probes[i].b), b1 = std::max(b1, probes[i].b);
  }
  // As many bins as bin() rounds the probes into.
  const int na = static_cast<int>((a1 - a0) / params.angle + 0.5f) + 1;
  const int nb = static_cast<int>((b1 - b0) / params.angle + 0.5f) + 1;
  std::vector<float> nearest(static_cast<size_t>(na) * static_cast<size_t>(nb), std::numeric_limits<float>::infinity());
  const auto bin = [&](float a, float b) {
    const int ia = static_cast<int>(std::floor((a - a0) / params.angle + 0.5f));
    const int ib = static_cast<int>(std::floor((b - b0) / params.angle + 0.5f));
    return ia < 0 || ia >= na || ib < 0 || ib >= nb ? -1 : ia * nb + ib;
  };
  // Directions a bin or more outside the probes' (bin() rounds, so the upper side needs one and a
  // half) fall in no bin: told without dividing, most of the scene.
  const float a_low = a0 - params.angle, a_high = a1 + 1.5f * params.angle;
  const float b_low = b0 - params.angle, b_high = b1 + 1.5f * params.angle;
  for (const auto& p : scene.points) {
    const float t = p.dot(forward);
    if (t <= 1e-3f) continue;  // behind the sensor
    const float along_right = p.dot(right), along_up = p.dot(up);
    if (along_right < a_low * t || along_right > a_high * t || along_up < b_low * t || along_up > b_high * t) continue;
    const int k = bin(along_right / t, along_up / t);
    if (k >= 0) nearest[static_cast<size_t>(k)] = std::min(nearest[static_cast<size_t>(k)], t);
  }
  for (size_t i = 0; i < cells.size(); ++i) {
    const int k = bin(probes[i].a, probes[i].b);
    const float t = k < 0 ? std::numeric_limits<float>::infinity() : nearest[static_cast<size_t>(k)];
    seen[i] = std::isfinite(t) && t >= probes[i].depth - params.margin;
  }
  return seen;
}

}  // namespace

float seatAreaShare(const std::vector<Eigen::Vector3f>& points, float width, float depth,
                    const SeatAreaParams& params) {
  const FootprintCells cells(width, depth, params.inner, params.cell);
  if (cells.degenerate()) return 0;
  const std::vector<char> seat = seatCells(points, cells, params);
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
  const FootprintCells cells(local.box.size.x(), local.box.size.y(), params.inner, params.cell);
  if (cells.degenerate()) return check;
  std::vector<Eigen::Vector3f> band;  // only what can count, in the box's frame above the floor
  for (const auto& p : scene.points) {
    const float height = p.z() - local.floor_z;  // boxFrame's z
    if (height >= params.from && height <= params.to) band.push_back(local.boxFrame(p));
  }
  const std::vector<char> seat = seatCells(band, cells, params);
  std::vector<char> seen = scene.map ? std::vector<char>(cells.size(), 1) : seenCells(scene, local, cells, params);
  int seat_count = 0, seen_count = 0;
  for (size_t i = 0; i < cells.size(); ++i) {
    seen[i] = seen[i] || seat[i];  // a point measured there was seen
    seat_count += seat[i];
    seen_count += seen[i];
  }
  check.seen = static_cast<float>(seen_count) / static_cast<float>(cells.size());
  if (seen_count == 0 || check.seen < params.min_seen) return check;
  check.looked = true;
  check.min_share = params.min_share;
  check.share = static_cast<float>(seat_count) / static_cast<float>(seen_count);
  return check;
}

}  // namespace ism
