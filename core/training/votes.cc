#include "core/training/votes.h"

namespace ism {

std::vector<TrainingVote> trainingVotes(const std::vector<const TrainingScan*>& scans, const Codebook& codebook) {
  std::vector<TrainingVote> votes;
  for (const auto* s : scans) {
    for (const auto& a : codebook.activate(s->features.descriptors, {ActivationStrategy::kKnn, 1, 0})) {
      const auto k = static_cast<size_t>(a.keypoint);
      votes.push_back({a.codeword, s->model_index, s->features.lrfs[k] * (s->object_center - s->features.positions[k])});
    }
  }
  return votes;
}

VoteTable packVotes(const std::vector<TrainingVote>& votes, int codebook_size, int excluded) {
  VoteTable table;
  table.offsets.assign(static_cast<size_t>(codebook_size) + 1, 0);
  for (const auto& v : votes) {
    if (v.model != excluded) ++table.offsets[static_cast<size_t>(v.codeword) + 1];
  }
  for (int c = 0; c < codebook_size; ++c) table.offsets[static_cast<size_t>(c) + 1] += table.offsets[static_cast<size_t>(c)];
  table.vectors.resize(table.offsets.back());
  std::vector<uint32_t> cursor(table.offsets.begin(), table.offsets.end() - 1);
  for (const auto& v : votes) {
    if (v.model != excluded) table.vectors[cursor[static_cast<size_t>(v.codeword)]++] = v.vector;
  }
  return table;
}

}  // namespace ism
