#pragma once
// A hypothesis: what the peak search finds and recognition returns, one object of a category.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/common/types.h"

namespace ism {

// A category that lost to a hypothesis of another at the same place, and how sure it was.
struct Alternative {
  std::string category;
  float confidence = 0;
};

// How the scene agrees with the category's best fitting training shape at the hypothesis
// (verification.h): of the shape's pixels the sensor looked at, how many it measured at the
// shape's depth, and how many it saw through.
struct Verification {
  int seen = 0;        // shape pixels with a measured depth not in front of the shape
  int consistent = 0;  // of them, at the shape's depth
  // The share of agreeing pixels, shrunk towards 0.5 by ten pixels' worth of each (a Beta(10, 10)
  // prior): a shape the scene hides but for a few pixels is neither confirmed nor refuted.
  float fit() const { return (static_cast<float>(consistent) + 10.0f) / (static_cast<float>(seen) + 20.0f); }
  // Agreeing pixels on surface a more confident hypothesis of the category explained (not in
  // `seen`): more of them than `consistent` makes this hypothesis that one's duplicate.
  int claimed = 0;
  bool duplicate() const { return claimed > consistent; }
  // How unlike the training shapes the scene's surface in the fitted box is, over height and
  // distance from the box's axis (verification.h, shapeProfile): 0 alike, 2 nothing in common.
  float profile_distance = 1.0f;
  int object = -1;     // the shape's training object (CategoryModel::objects)
  // `seen` and `consistent` of the fitted shape's top part alone (VerificationParams::top_part: a
  // chair's backrest, a couch's back), which the whole shape's fit can outweigh (top_seen.h).
  int top_seen = 0, top_consistent = 0;
  float yaw = 0;       // its heading about up in the gravity frame (rad)
  Eigen::Vector3f center = Eigen::Vector3f::Zero();  // its box centre, scene coordinates
  // The surface the best pose explains: 5 cm cubes of the gravity frame, sorted. In a frame, the
  // cube of the measured point behind each agreeing shape pixel; in a map, the cube of each shape
  // point with a measured point within about a voxel. Two hypotheses of different categories on
  // one object explain the same surface (suppression.h).
  std::vector<uint64_t> explained;
};

struct Hypothesis {
  std::string category;
  float score = 0;       // summed vote weight around the centre
  float threshold = 0;   // the threshold the score was compared with
  // How far above its category's threshold: what the seed's selection ranks hypotheses of
  // different categories by, since raw scores are not comparable across categories (LW and AW
  // scores scale with 1/|Occ|, which differs per category's vote table).
  float relativeScore() const { return threshold > 0 ? score / threshold : score; }
  // In [0, 1], the same scale for every category: the probability that an object of the category
  // is there, from the category's calibration; without one, 1 - 2^-(score / threshold), which is
  // 0.5 at the threshold.
  float confidence = 0;
  Eigen::Vector3f center = Eigen::Vector3f::Zero();  // weighted mean of the votes in the peak
  // Upright (z along the scene's up, bottom on the floor when there is one) from the training
  // objects whose votes make the peak, when the model's votes are upright; else the PCA box of
  // the supporting keypoints.
  OrientedBox box;
  bool upright_box = false;
  // Keypoints that voted into the peak, and into the peaks of its category merged into it
  // (SuppressionParams::merge_support), each once; a table's answer, those that voted into the bin
  // at its box's centre (SuppressionParams::top_support).
  int support = 0;
  Eigen::Vector3f support_centroid = Eigen::Vector3f::Zero();
  bool passed_selection = true;  // box volume within range and longest edge below the maximum
  // The scene refutes the category but shows an object there, of which this is the best answer (a
  // couch on a bed's level top, open_top.h): it keeps its place among the answers per object, so
  // that no other category's answer takes the same object, and is then rejected.
  bool refuted = false;
  std::vector<Alternative> alternatives;  // best first
  std::optional<Verification> verification;  // default preset, models with training shapes
  std::vector<Eigen::Vector3f> support_keypoints;  // when asked for
  std::vector<int> support_indices;  // the supporting keypoints as indices into the Features
};

// Makes `indices` (ascending keypoints of `features`) the hypothesis' support: the indices, their
// positions, their count and centroid.
inline void setSupport(Hypothesis& h, std::vector<int> indices, const Features& features) {
  h.support_indices = std::move(indices);
  h.support_keypoints.clear();
  h.support_centroid.setZero();
  for (int k : h.support_indices) {
    h.support_keypoints.push_back(features.positions[static_cast<size_t>(k)]);
    h.support_centroid += h.support_keypoints.back();
  }
  h.support = static_cast<int>(h.support_indices.size());
  if (h.support > 0) h.support_centroid /= static_cast<float>(h.support);
}

}  // namespace ism
