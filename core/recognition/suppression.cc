#include "core/recognition/suppression.h"

#include <algorithm>
#include <cmath>

#include "core/common/upright_box.h"

namespace ism {
namespace {

bool insideFootprint(const Eigen::Vector3f& p, const UprightBox& box) {
  const Eigen::Vector2f local = Eigen::Rotation2Df(-box.yaw) * (p.head<2>() - box.center.head<2>());
  return std::abs(local.x()) <= box.size.x() / 2 && std::abs(local.y()) <= box.size.y() / 2;
}

}  // namespace

std::vector<Hypothesis> suppressOverlaps(std::vector<Hypothesis> hypotheses, const Eigen::Matrix3f& to_gravity,
                                         const SuppressionParams& params) {
  std::stable_sort(hypotheses.begin(), hypotheses.end(),
                   [](const Hypothesis& a, const Hypothesis& b) { return a.confidence > b.confidence; });
  std::vector<Hypothesis> kept;
  std::vector<UprightBox> boxes;
  for (auto& h : hypotheses) {
    const UprightBox box = uprightBoxOf(h.box, to_gravity);
    size_t winner = kept.size();
    for (size_t i = 0; i < kept.size() && winner == kept.size(); ++i) {
      if (intersectionOverUnion(boxes[i], box) >= params.min_iou || insideFootprint(box.center, boxes[i]) ||
          insideFootprint(boxes[i].center, box)) {
        winner = i;
      }
    }
    if (winner == kept.size()) {
      kept.push_back(std::move(h));
      boxes.push_back(box);
      continue;
    }
    Hypothesis& w = kept[winner];
    if (h.category == w.category) continue;  // another peak of the same object
    const bool listed = std::any_of(w.alternatives.begin(), w.alternatives.end(),
                                    [&](const Alternative& a) { return a.category == h.category; });
    if (!listed) w.alternatives.push_back({h.category, h.confidence});  // most confident of its category first
  }
  return kept;
}

}  // namespace ism
