#include "core/recognition/open_top.h"

namespace ism {

OpenTopCheck checkOpenTop(const VerificationScene& scene, const Hypothesis& hypothesis, const OpenTopParams& params) {
  OpenTopCheck check;
  if (!params.enabled || !hypothesis.upright_box || !hypothesis.verification) return check;
  const SceneBox local = sceneBox(scene, hypothesis);
  const float top = local.top();
  check.looked = true;
  check.max_share = params.max_share;
  for (const auto& p : scene.points) {
    if (!local.overFootprint(p, params.inner)) continue;
    if (p.z() > top + params.from && p.z() < top + params.to) {
      ++check.above;
    } else if (p.z() > local.floor_z + params.body_from && p.z() < top) {
      ++check.body;
    }
  }
  return check;
}

}  // namespace ism
