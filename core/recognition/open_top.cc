#include "core/recognition/open_top.h"

#include <algorithm>

namespace ism {

OpenTopCheck checkOpenTop(const VerificationScene& scene, const Hypothesis& hypothesis, const OpenTopParams& params) {
  OpenTopCheck check;
  if (!params.enabled || !hypothesis.upright_box || !hypothesis.verification) return check;
  const SceneBox local = sceneBox(scene, hypothesis);
  const float top = local.top();
  check.looked = true;
  check.max_share = params.max_share;
  check.min_upper = params.min_upper;
  for (const auto& p : scene.points) {
    const float height = p.z() - local.floor_z;
    if (height > params.upper_from && height < params.upper_to && local.overFootprint(p)) {
      ++check.upper;
    }
    if (!local.overFootprint(p, params.inner)) continue;
    if (p.z() > top + params.from && p.z() < top + params.to) {
      ++check.above;
    } else if (p.z() > local.floor_z + params.body_from && p.z() < top) {
      ++check.body;
    }
  }
  return check;
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
