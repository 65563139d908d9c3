#include "core/recognition/ensemble.h"

#include <algorithm>

#include "core/common/upright_box.h"

namespace ism {

std::vector<PeakGroup> groupPeaks(const std::vector<std::vector<Hypothesis>>& peaks, const Eigen::Matrix3f& to_gravity,
                                  const EnsembleParams& params) {
  struct Peak {
    float confidence;
    int model, index;
  };
  std::vector<Peak> order;
  for (size_t m = 0; m < peaks.size(); ++m) {
    for (size_t i = 0; i < peaks[m].size(); ++i) {
      order.push_back({peaks[m][i].confidence, static_cast<int>(m), static_cast<int>(i)});
    }
  }
  std::stable_sort(order.begin(), order.end(), [](const Peak& a, const Peak& b) { return a.confidence > b.confidence; });
  std::vector<PeakGroup> groups;
  std::vector<UprightBox> boxes;  // of each group's first peak
  for (const Peak& p : order) {
    const Hypothesis& h = peaks[static_cast<size_t>(p.model)][static_cast<size_t>(p.index)];
    const UprightBox box = uprightBoxOf(h.box, to_gravity);
    int into = -1;
    float best_iou = params.min_iou;
    for (size_t g = 0; g < groups.size() && peaks.size() > 1; ++g) {
      if (groups[g].peak[static_cast<size_t>(p.model)] >= 0) continue;
      const float iou = intersectionOverUnion(box, boxes[g]);
      if (iou >= best_iou) best_iou = iou, into = static_cast<int>(g);
    }
    if (into < 0) {
      into = static_cast<int>(groups.size());
      groups.push_back({std::vector<int>(peaks.size(), -1), p.model});
      boxes.push_back(box);
    }
    groups[static_cast<size_t>(into)].peak[static_cast<size_t>(p.model)] = p.index;
  }
  return groups;
}

}  // namespace ism
