#include "core/recognition/bare_floor.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/recognition/footprint_cells.h"

namespace ism {
namespace {

// Cells of the inner footprint: 1 floor, 2 covered (both may be set).
struct Cells {
  FootprintCells grid;
  std::vector<char> marks;
  Cells(float w, float d, const BareFloorParams& params) : grid(w, d, params.inner, params.cell), marks(grid.size(), 0) {}
  // (x, y) about the footprint's centre along its sides; null outside the inner footprint.
  char* at(float x, float y) {
    const int i = grid.of(x, y);
    return i < 0 ? nullptr : &marks[static_cast<size_t>(i)];
  }
  void add(const Eigen::Vector3f& p, float top, const BareFloorParams& params) {
    char* cell = at(p.x(), p.y());
    if (cell == nullptr) return;
    if (std::abs(p.z()) <= params.band) *cell |= 1;
    if (p.z() > params.body_from && p.z() < top + params.over) *cell |= 2;
  }
  float share(char mark) const {
    return static_cast<float>(std::count(marks.begin(), marks.end(), mark)) / static_cast<float>(marks.size());
  }
  float uncovered() const {
    const auto n = std::count_if(marks.begin(), marks.end(), [](char m) { return (m & 2) == 0; });
    return static_cast<float>(n) / static_cast<float>(marks.size());
  }
};

}  // namespace

BareFloorCheck checkBareFloor(const VerificationScene& scene, const Hypothesis& hypothesis, bool covering,
                              const BareFloorParams& params) {
  BareFloorCheck check;
  if (!params.enabled || !covering || !hypothesis.upright_box || !hypothesis.verification) return check;
  if (params.maps_only && !scene.map) return check;
  const SceneBox local = sceneBox(scene, hypothesis);
  check.looked = true;
  check.max_bare = params.max_bare;
  const float top = local.top() - local.floor_z;
  Cells cells(local.box.size.x(), local.box.size.y(), params);
  for (const auto& p : scene.points) cells.add(local.boxFrame(p), top, params);
  check.bare = cells.share(1);
  return check;
}

float bareShare(const std::vector<Eigen::Vector3f>& points, float width, float depth, float top,
                const BareFloorParams& params) {
  Cells cells(width, depth, params);
  for (const auto& p : points) cells.add(p, top, params);
  return cells.share(1);
}

bool footprintCoveredTrained(const CategoryModel& category, const BareFloorParams& params) {
  if (!params.enabled) return false;
  bool any = false;
  for (const auto& o : category.objects) {
    if (o.surface.empty()) continue;  // a shape calibration holds out
    Cells cells(o.size.x(), o.size.y(), params);
    for (const auto& p : o.surface) cells.add(p, o.size.z(), params);
    if (cells.uncovered() >= params.max_bare) return false;
    any = true;
  }
  return any;
}

}  // namespace ism
