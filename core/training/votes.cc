#include "core/training/votes.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/recognition/voting.h"

namespace ism {

std::vector<TrainingVote> trainingVotes(const std::vector<const TrainingScan*>& scans, const Codebook& codebook,
                                        VoteFrame frame) {
  std::vector<TrainingVote> votes;
  for (const auto* s : scans) {
    const Features& f = s->features;
    const bool heights = f.heights.size() == f.size();
    for (const auto& a : codebook.activate(f.descriptors, {ActivationStrategy::kKnn, 1, 0})) {
      const auto k = static_cast<size_t>(a.keypoint);
      const Eigen::Matrix3f r = voteFrame(f, k, frame);
      // Meshes are placed with their own axes along the world's, so the object's x is world x;
      // in an upright frame (z = world z) its heading is minus the frame's own.
      const float heading = frame == VoteFrame::kUpright ? -std::atan2(r(0, 1), r(0, 0)) : std::numeric_limits<float>::quiet_NaN();
      votes.push_back({a.codeword, s->model_index, r * (s->object_center - f.positions[k]),
                       heights ? f.heights[k] : std::numeric_limits<float>::quiet_NaN(), heading});
    }
  }
  return votes;
}

VoteTable packVotes(const std::vector<TrainingVote>& votes, int codebook_size, int excluded) {
  std::vector<bool> held_out;
  if (excluded >= 0) {
    held_out.assign(static_cast<size_t>(excluded) + 1, false);
    held_out.back() = true;
  }
  return packVotes(votes, codebook_size, held_out);
}

VoteTable packVotes(const std::vector<TrainingVote>& votes, int codebook_size, const std::vector<bool>& held_out) {
  const auto excludedModel = [&](int model) {
    return model >= 0 && static_cast<size_t>(model) < held_out.size() && held_out[static_cast<size_t>(model)];
  };
  VoteTable table;
  table.offsets.assign(static_cast<size_t>(codebook_size) + 1, 0);
  for (const auto& v : votes) {
    if (!excludedModel(v.model)) ++table.offsets[static_cast<size_t>(v.codeword) + 1];
  }
  for (int c = 0; c < codebook_size; ++c) table.offsets[static_cast<size_t>(c) + 1] += table.offsets[static_cast<size_t>(c)];
  table.vectors.resize(table.offsets.back());
  const bool heights = !votes.empty() && std::all_of(votes.begin(), votes.end(), [](const TrainingVote& v) {
    return std::isfinite(v.height);
  });
  const bool headings = !votes.empty() && std::all_of(votes.begin(), votes.end(), [](const TrainingVote& v) {
    return std::isfinite(v.heading) && v.model >= 0 && v.model <= 0xffff;
  });
  if (headings) {
    table.objects.resize(table.vectors.size());
    table.headings.resize(table.vectors.size());
  }
  std::vector<const TrainingVote*> order;
  order.reserve(votes.size());
  for (const auto& v : votes) order.push_back(&v);
  if (heights) {
    table.heights.resize(table.vectors.size());
    std::stable_sort(order.begin(), order.end(), [](const TrainingVote* a, const TrainingVote* b) { return a->height < b->height; });
  }
  std::vector<uint32_t> cursor(table.offsets.begin(), table.offsets.end() - 1);
  for (const TrainingVote* v : order) {
    if (excludedModel(v->model)) continue;
    const uint32_t at = cursor[static_cast<size_t>(v->codeword)]++;
    table.vectors[at] = v->vector;
    if (heights) table.heights[at] = v->height;
    if (headings) {
      table.objects[at] = static_cast<uint16_t>(v->model);
      table.headings[at] = v->heading;
    }
  }
  return table;
}

}  // namespace ism
