#pragma once
// One object, one answer. Peaks of one category on one object (a table's long top gives
// several) merge into the most confident; hypotheses of different categories on one object
// compete, the most confident wins, and the others stay on it as alternatives. Two hypotheses
// are on one object when their upright boxes overlap by at least `min_iou` (3D IoU, as VoteNet's
// non-maximum suppression), or when the centre of one lies inside the other's footprint and, for
// two verified hypotheses of different categories, the more confident explains at least
// `min_shared_surface` of the other's verified surface.
#include <Eigen/Core>
#include <vector>

#include "core/recognition/hypothesis.h"

namespace ism {

struct SuppressionParams {
  float min_iou = 0.25f;
  float min_shared_surface = 0.5f;
  // false: across categories too, a centre in the other's footprint alone makes one object.
  bool shared_surface = true;
  // The supporting keypoints of the peaks a hypothesis absorbs of its own category join its own
  // (Hypothesis::support, support_keypoints, support_indices, support_centroid): one answer on a
  // long table is supported by every peak its top gave. Without top_support, recognition also
  // gives a table's answer the support of the weaker, unverified peaks whose centre its box holds
  // (recognizer.cc). Off where the support still feeds the confidence (recognition's merge before
  // verification, the calibration's), which learned it per peak.
  bool merge_support = true;
  // A verified answer of a flat-topped category, whose box spans the table top the scene measured
  // (top_extent.h), is supported by the keypoints with a vote in the bin at its box's centre: the
  // seed's support of a hypothesis there. Its peaks stand wherever the top's keypoints happened to
  // vote most, often at one end of a long top; the box stands on the top itself. Recognition
  // collects them after the answers are chosen (recognizer.cc); it replaces merge_support's and
  // the weak peaks' support for those answers. As the mean-shift search of Leibe, Leonardis and
  // Schiele's ISM ("Robust object detection with interleaved categorization and segmentation",
  // IJCV 2008) takes the votes inside its kernel at the position it settles on.
  bool top_support = true;
};

// `from`'s supporting keypoints join `into`'s, each once (both lists ascend by index, as the Hough
// space makes them); the centroid is made again from the positions when both carry them, else it
// stays `into`'s.
void mergeSupport(Hypothesis& into, const Hypothesis& from);

// `hypotheses` in any order, with boxes in scene coordinates; `to_gravity` turns them into the
// gravity frame (Gravity::toGravity). Returns the survivors, most confident first.
std::vector<Hypothesis> suppressOverlaps(std::vector<Hypothesis> hypotheses, const Eigen::Matrix3f& to_gravity,
                                         const SuppressionParams& params = {});

}  // namespace ism
