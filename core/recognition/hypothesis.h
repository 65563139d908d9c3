#pragma once
// A hypothesis: what the peak search finds and recognition returns, one object of a category.
#include <string>
#include <vector>

#include "core/common/types.h"

namespace ism {

struct Hypothesis {
  std::string category;
  float score = 0;       // summed vote weight around the centre
  float threshold = 0;   // the threshold the score was compared with
  // How far above its category's threshold: what ranks hypotheses of different categories
  // against each other, since raw scores are not comparable across categories (LW and AW
  // scores scale with 1/|Occ|, which differs per category's vote table).
  float relativeScore() const { return threshold > 0 ? score / threshold : score; }
  Eigen::Vector3f center = Eigen::Vector3f::Zero();  // weighted mean of the votes in the peak
  OrientedBox box;       // PCA box of the supporting keypoints
  int support = 0;       // keypoints that voted into the peak
  Eigen::Vector3f support_centroid = Eigen::Vector3f::Zero();
  bool passed_selection = true;  // box volume within range and longest edge below the maximum
  std::vector<Eigen::Vector3f> support_keypoints;  // when asked for
};

}  // namespace ism
