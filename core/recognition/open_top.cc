#include "core/recognition/open_top.h"

#include <cmath>

#include "core/common/upright_box.h"

namespace ism {

OpenTopCheck checkOpenTop(const VerificationScene& scene, const Hypothesis& hypothesis, const OpenTopParams& params) {
  OpenTopCheck check;
  if (!params.enabled || !hypothesis.upright_box || !hypothesis.verification) return check;
  const UprightBox box = uprightBoxOf(hypothesis.box, scene.to_gravity);
  const Eigen::Vector3f centre = box.center - scene.to_gravity * scene.origin;  // scene.points' frame
  const float floor_z = scene.floor_z.value_or(centre.z() - box.size.z() / 2);
  const float top = centre.z() + box.size.z() / 2;
  const float c = std::cos(box.yaw), s = std::sin(box.yaw);
  const Eigen::Vector2f half = params.inner * box.size.head<2>() / 2;
  check.looked = true;
  for (const auto& p : scene.points) {
    const float dx = p.x() - centre.x(), dy = p.y() - centre.y();
    if (std::abs(c * dx + s * dy) > half.x() || std::abs(-s * dx + c * dy) > half.y()) continue;
    if (p.z() > top + params.from && p.z() < top + params.to) {
      ++check.above;
    } else if (p.z() > floor_z + params.body_from && p.z() < top) {
      ++check.body;
    }
  }
  return check;
}

}  // namespace ism
