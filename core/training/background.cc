#include "core/training/background.h"

#include <numeric>

#include "core/common/error.h"

namespace ism {

std::vector<int> activationCounts(const Codebook& codebook, const std::vector<const TrainingScan*>& scans,
                                  const ActivationParams& activation) {
  std::vector<int> counts(static_cast<size_t>(codebook.size()), 0);
  for (const TrainingScan* s : scans) {
    if (s->features.size() == 0) continue;
    for (const Activation& a : codebook.activate(s->features.descriptors, activation)) ++counts[static_cast<size_t>(a.codeword)];
  }
  return counts;
}

std::vector<float> codewordWeights(const std::vector<int>& category_counts, const std::vector<int>& background_counts) {
  if (category_counts.size() != background_counts.size()) {
    throw Error(ErrorCode::kInvalidInput, "codeword weights: " + std::to_string(category_counts.size()) +
                                              " category counts against " + std::to_string(background_counts.size()) +
                                              " background counts");
  }
  std::vector<float> weights(category_counts.size(), 1.0f);
  const double category_total = std::accumulate(category_counts.begin(), category_counts.end(), 0.0);
  const double background_total = std::accumulate(background_counts.begin(), background_counts.end(), 0.0);
  if (!(category_total > 0) || !(background_total > 0)) return weights;
  for (size_t c = 0; c < weights.size(); ++c) {
    const double own = category_counts[c] / category_total, other = background_counts[c] / background_total;
    // A codeword the category never activates casts no votes of it: its weight does not matter,
    // and 1 keeps it inside (0, 1].
    if (own > 0) weights[c] = static_cast<float>(own / (own + other));
  }
  return weights;
}

}  // namespace ism
