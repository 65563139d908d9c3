#include "core/recognition/suppression.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <utility>

#include "core/common/upright_box.h"

namespace ism {
namespace {

// The share of `h`'s explained surface that `winner` explains too; -1 when either is unverified.
float sharedSurface(const Hypothesis& winner, const Hypothesis& h) {
  if (!winner.verification || !h.verification || h.verification->explained.empty()) return -1;
  const auto& a = winner.verification->explained;
  const auto& b = h.verification->explained;
  size_t shared = 0;
  for (size_t i = 0, j = 0; i < a.size() && j < b.size();) {
    if (a[i] < b[j]) {
      ++i;
    } else if (b[j] < a[i]) {
      ++j;
    } else {
      ++shared, ++i, ++j;
    }
  }
  return static_cast<float>(shared) / static_cast<float>(b.size());
}

// Boxes that overlap by less than min_iou. Peaks of one category whose centres fall in each
// other's footprint are one object (a table's long top gives several). Across categories a centre
// in the other's footprint is not enough: a chair pushed under a desk has its centre in the desk's
// footprint and is an object of its own. There the verified surface decides, as the
// multiple-assignment term of Aldoma et al.'s global verification does: the less confident is the
// same object when the winner explains most of the surface it explains. Unverified, they are one
// object when either centre lies in the other's footprint.
bool sameObject(const Hypothesis& winner, const UprightBox& winner_box, const Hypothesis& h, const UprightBox& box,
                const SuppressionParams& params) {
  if (!insideFootprint(box.center, winner_box) && !insideFootprint(winner_box.center, box)) return false;
  if (winner.category == h.category || !params.shared_surface) return true;
  const float shared = sharedSurface(winner, h);
  return shared < 0 || shared >= params.min_shared_surface;
}

}  // namespace

void mergeSupport(Hypothesis& into, const Hypothesis& from) {
  if (from.support_indices.empty()) return;
  const bool positions = into.support_keypoints.size() == into.support_indices.size() &&
                         from.support_keypoints.size() == from.support_indices.size();
  using Keypoint = std::pair<int, Eigen::Vector3f>;
  const auto keypoints = [&](const Hypothesis& h) {
    std::vector<Keypoint> out;
    for (size_t k = 0; k < h.support_indices.size(); ++k) {
      out.emplace_back(h.support_indices[k], positions ? h.support_keypoints[k] : Eigen::Vector3f::Zero());
    }
    return out;
  };
  const auto a = keypoints(into), b = keypoints(from);
  std::vector<Keypoint> both;
  const auto byIndex = [](const Keypoint& x, const Keypoint& y) { return x.first < y.first; };
  std::set_union(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(both), byIndex);
  into.support_indices.clear();
  for (const auto& keypoint : both) into.support_indices.push_back(keypoint.first);
  into.support = static_cast<int>(both.size());
  if (!positions) return;  // the centroid stays the peak's own
  into.support_keypoints.clear();
  into.support_centroid.setZero();
  for (const auto& keypoint : both) {
    into.support_keypoints.push_back(keypoint.second);
    into.support_centroid += keypoint.second;
  }
  into.support_centroid /= static_cast<float>(both.size());
}

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
      if (intersectionOverUnion(boxes[i], box) >= params.min_iou || sameObject(kept[i], boxes[i], h, box, params)) {
        winner = i;
      }
    }
    if (winner == kept.size()) {
      kept.push_back(std::move(h));
      boxes.push_back(box);
      continue;
    }
    Hypothesis& w = kept[winner];
    if (h.category == w.category && params.merge_support) mergeSupport(w, h);
    if (h.category == w.category || h.refuted) continue;  // another peak of the same object, or not an answer
    const bool listed = std::any_of(w.alternatives.begin(), w.alternatives.end(),
                                    [&](const Alternative& a) { return a.category == h.category; });
    if (!listed) w.alternatives.push_back({h.category, h.confidence});  // most confident of its category first
  }
  return kept;
}

}  // namespace ism
