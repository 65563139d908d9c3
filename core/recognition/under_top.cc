#include "core/recognition/under_top.h"

#include <algorithm>
#include <vector>

#include "core/recognition/footprint_cells.h"

namespace ism {

float openUnderShare(const std::vector<Eigen::Vector3f>& points, float width, float depth, float top,
                     const UnderTopParams& params) {
  const FootprintCells cells(width, depth, params.inner, params.cell);
  std::vector<char> open(cells.size(), 0);
  for (const auto& p : points) {
    if (p.z() < -params.band || p.z() > top - params.below) continue;
    const int i = cells.of(p.x(), p.y());
    if (i >= 0) open[static_cast<size_t>(i)] = 1;
  }
  return static_cast<float>(std::count(open.begin(), open.end(), 1)) / static_cast<float>(open.size());
}

UnderTopCheck checkUnderTop(const VerificationScene& scene, const Hypothesis& hypothesis,
                            const UnderTopParams& params) {
  UnderTopCheck check;
  if (!params.enabled || !hypothesis.upright_box || !hypothesis.verification) return check;
  const SceneBox local = sceneBox(scene, hypothesis);
  check.looked = true;
  check.min_open = params.min_open;
  const float top = local.top() - local.floor_z;
  const int near = params.near_edge > 0 ? sensorSide(scene, local) : -1;
  std::vector<Eigen::Vector3f> under;  // only what can count: below the top, in the box's frame
  for (const auto& p : scene.points) {
    const Eigen::Vector3f q = local.boxFrame(p);
    if (q.z() > top - params.below) continue;
    if (near >= 0 && local.inFrom(near, q) < params.near_edge) continue;  // a closed front
    under.push_back(q);
  }
  check.open = openUnderShare(under, local.box.size.x(), local.box.size.y(), top, params);
  return check;
}

}  // namespace ism
