#include "core/recognition/under_top.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace ism {

float openUnderShare(const std::vector<Eigen::Vector3f>& points, float width, float depth, float top,
                     const UnderTopParams& params) {
  const float w = params.inner * width, d = params.inner * depth;
  const int nx = std::max(1, static_cast<int>(std::ceil(w / params.cell)));
  const int ny = std::max(1, static_cast<int>(std::ceil(d / params.cell)));
  std::vector<char> open(static_cast<size_t>(nx) * static_cast<size_t>(ny), 0);
  for (const auto& p : points) {
    if (p.z() < -params.band || p.z() > top - params.below) continue;
    const float u = (p.x() + w / 2) / w, v = (p.y() + d / 2) / d;
    if (u < 0 || u >= 1 || v < 0 || v >= 1) continue;
    open[static_cast<size_t>(u * static_cast<float>(nx)) * static_cast<size_t>(ny) +
         static_cast<size_t>(v * static_cast<float>(ny))] = 1;
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
  std::vector<Eigen::Vector3f> under;  // only what can count: below the top, in the box's frame
  for (const auto& p : scene.points) {
    const Eigen::Vector3f q = local.boxFrame(p);
    if (q.z() <= top - params.below) under.push_back(q);
  }
  check.open = openUnderShare(under, local.box.size.x(), local.box.size.y(), top, params);
  return check;
}

}  // namespace ism
