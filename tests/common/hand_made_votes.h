#pragma once
// Hand-made models and features for the recognition stages: a one-category model whose vote
// table holds given vectors, and keypoints whose votes land exactly where a test wants them,
// so that votes, peaks and hypotheses have known answers.
#include <vector>

#include "core/model/model.h"

namespace ism::testing {

// A one-category model whose global codebook is the n unit vectors of R^n and whose vote table
// holds `votes[i]` under codeword i.
inline Model modelWithVotes(const std::vector<std::vector<Eigen::Vector3f>>& votes, float bin_size = 0.1f) {
  Model m;
  const auto n = static_cast<Eigen::Index>(votes.size());
  m.global_codebook = Codebook(DescriptorMatrix::Identity(n, n));
  CategoryModel c;
  c.name = "chair";
  c.bin_size = bin_size;
  c.global_votes.offsets.push_back(0);
  for (const auto& list : votes) {
    c.global_votes.vectors.insert(c.global_votes.vectors.end(), list.begin(), list.end());
    c.global_votes.offsets.push_back(static_cast<uint32_t>(c.global_votes.vectors.size()));
  }
  c.box = {0.0f, 1.0f, 1.0f};
  c.thresholds[{CodebookType::kGlobal, ActivationStrategy::kKnn, VoteWeighting::kLocalization}] = 0.5f;
  m.categories.push_back(c);
  return m;
}

// The default strategy (global codebook, k-NN) with weighting `w`.
inline Strategy strategy(VoteWeighting w) {
  Strategy s;
  s.weighting = w;
  return s;
}

// Keypoints around `center` with random LRFs; codeword i stores keypoint i's vote to the centre.
struct HandMadeObject {
  Features features;
  std::vector<std::vector<Eigen::Vector3f>> votes;
  std::vector<Activation> activations;
};

// `spread` moves each stored vote by up to that much so that the peak is a cluster, not a point.
inline HandMadeObject handMadeObject(const Eigen::Vector3f& center, int keypoints, int first_keypoint = 0,
                                     float spread = 0) {
  HandMadeObject o;
  for (int i = 0; i < keypoints; ++i) {
    const Eigen::Vector3f p = center + 0.4f * Eigen::Vector3f::Random();
    const Eigen::Matrix3f lrf = Eigen::Quaternionf::UnitRandom().toRotationMatrix().transpose();
    o.features.positions.push_back(p);
    o.features.lrfs.push_back(lrf);
    o.votes.push_back({lrf * (center - p + spread * Eigen::Vector3f::Random())});
    o.activations.push_back({first_keypoint + i, first_keypoint + i, 0.0f});
  }
  return o;
}

}  // namespace ism::testing
