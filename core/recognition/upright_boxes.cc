#include "core/recognition/upright_boxes.h"

#include <cmath>

#include "core/common/upright_box.h"

namespace ism {

bool hasUprightVotes(const VoteCaster& caster) {
  const VoteTable& table = caster.table();
  return !table.objects.empty() && table.objects.size() == table.vectors.size() &&
         table.headings.size() == table.vectors.size() && !caster.category().objects.empty();
}

void estimateUprightBox(const VoteCaster& caster, float half_edge, Hypothesis& peak) {
  const Features& features = caster.features();
  if (!features.gravity || !hasUprightVotes(caster)) return;
  const Gravity& gravity = *features.gravity;
  const Eigen::Matrix3f to_gravity = gravity.toGravity();
  const VoteTable& table = caster.table();
  const std::vector<TrainingObject>& objects = caster.category().objects;
  double weight = 0;
  Eigen::Vector3d size = Eigen::Vector3d::Zero();
  double cos2 = 0, sin2 = 0;
  VoteChunk chunk;
  for (int k : peak.support_indices) {
    const auto keypoint = static_cast<size_t>(k);
    // The heading of the keypoint's frame about up, in the gravity frame.
    const Eigen::Vector3f x = to_gravity * caster.frame(keypoint).row(0).transpose();
    const float frame_heading = std::atan2(x.y(), x.x());
    caster.forEachVoteInCube(keypoint, peak.center, half_edge, chunk, [&](float w, uint32_t v) {
      const TrainingObject& object = objects[table.objects[v]];
      const double heading = 2.0 * (frame_heading + table.headings[v]);
      weight += w;
      size += w * object.size.cast<double>();
      cos2 += w * std::cos(heading);
      sin2 += w * std::sin(heading);
    });
  }
  if (!(weight > 0)) return;
  UprightBox box;
  box.size = (size / weight).cast<float>();
  box.yaw = static_cast<float>(0.5 * std::atan2(sin2, cos2));
  box.center = to_gravity * peak.center;
  // Furniture stands on the floor: the box's bottom is there, whatever noise moved the centre.
  if (gravity.hasFloor()) box.center.z() = *gravity.floor_level + box.size.z() / 2;
  peak.box = box.toScene(to_gravity);
  peak.upright_box = true;
}

}  // namespace ism
