#include "core/training/leave_one_out.h"


#include "core/recognition/voting.h"
#include "core/training/parallel_for.h"
#include "core/training/statistics.h"

namespace ism {
namespace {

const std::vector<VoteWeighting> kWeightings{VoteWeighting::kCategorization, VoteWeighting::kLocalization,
                                             VoteWeighting::kActivation};

// Per model m, a one-category model whose votes are all but model m's.
std::vector<Model> heldOutModels(const LeaveOneOutInput& input) {
  std::vector<Model> held_out(static_cast<size_t>(input.models));
  for (int m = 0; m < input.models; ++m) {
    CategoryModel reduced;
    reduced.name = input.category;
    reduced.bin_size = input.bin_size;
    VoteTable& table = input.codebook_type == CodebookType::kGlobal ? reduced.global_votes : reduced.own_votes;
    table = packVotes(input.votes, input.codebook.size(), m);
    table.codeword_weights = input.codeword_weights;
    held_out[static_cast<size_t>(m)].categories.push_back(std::move(reduced));
    held_out[static_cast<size_t>(m)].voting = input.voting;
  }
  return held_out;
}

}  // namespace

std::vector<LeaveOneOutThreshold> leaveOneOutThresholds(const LeaveOneOutInput& input,
                                                        const std::vector<ActivationParams>& activations, float threshold_floor,
                                                        int threads) {
  const std::vector<Model> held_out = heldOutModels(input);
  const size_t strategies = activations.size() * kWeightings.size();
  // scores[scan][activation * weightings + weighting]
  std::vector<std::vector<double>> scores(input.scans.size(), std::vector<double>(strategies));
  parallelFor(static_cast<int>(input.scans.size()), threads, [&](int i) {
    const TrainingScan& s = *input.scans[static_cast<size_t>(i)];
    const Model& without = held_out[static_cast<size_t>(s.model_index)];
    for (size_t a = 0; a < activations.size(); ++a) {
      const auto activated = input.codebook.activate(s.features.descriptors, activations[a]);
      for (size_t w = 0; w < kWeightings.size(); ++w) {
        const auto votes = castVotes(without, 0, s.features, activated, {input.codebook_type, activations[a], kWeightings[w]});
        scores[static_cast<size_t>(i)][a * kWeightings.size() + w] = scoreAt(votes, s.object_center, input.bin_size);
      }
    }
  });
  std::vector<LeaveOneOutThreshold> thresholds;
  for (size_t a = 0; a < activations.size(); ++a) {
    for (size_t w = 0; w < kWeightings.size(); ++w) {
      std::vector<double> values;
      for (const auto& s : scores) values.push_back(s[a * kWeightings.size() + w]);
      const MeanStd stats = meanStd(values);
      const double seed_rule = stats.mean - stats.std, floored_value = threshold_floor * stats.mean;
      LeaveOneOutThreshold t;
      t.key = {input.codebook_type, activations[a].strategy, kWeightings[w]};
      t.mean = stats.mean;
      t.std = stats.std;
      t.floored = seed_rule < floored_value;
      t.threshold = static_cast<float>(t.floored ? floored_value : seed_rule);
      thresholds.push_back(t);
    }
  }
  return thresholds;
}

}  // namespace ism
