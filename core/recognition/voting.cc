#include "core/recognition/voting.h"

#include <cmath>
#include <limits>
#include <string>

#include "core/common/error.h"

namespace ism {
namespace {

const VoteTable& votesOf(const CategoryModel& category, CodebookType type) {
  return type == CodebookType::kGlobal ? category.global_votes : category.own_votes;
}

}  // namespace

VoteCaster::VoteCaster(const Model& model, int category_index, const Features& features,
                       const std::vector<Activation>& activations, const Strategy& strategy)
    : category_(model.categories.at(static_cast<size_t>(category_index))),
      table_(votesOf(category_, strategy.codebook)),
      features_(features),
      weighting_(strategy.weighting),
      offsets_(features.size() + 1, 0),
      vote_offsets_(features.size() + 1, 0) {
  if (table_.empty()) return;
  const int codewords = static_cast<int>(table_.offsets.size()) - 1;
  for (const auto& a : activations) {
    if (a.keypoint < 0 || static_cast<size_t>(a.keypoint) >= features.size() || a.codeword < 0 ||
        a.codeword >= codewords) {
      throw Error(ErrorCode::kInvalidInput, "castVotes: activation (keypoint " + std::to_string(a.keypoint) +
                                                ", codeword " + std::to_string(a.codeword) + ") is out of range for " +
                                                std::to_string(features.size()) + " keypoints and " +
                                                std::to_string(codewords) + " codewords of category '" +
                                                category_.name + "'");
    }
    ++offsets_[static_cast<size_t>(a.keypoint) + 1];
    votes_ += table_.occurrences(a.codeword);
  }
  for (size_t k = 0; k < features.size(); ++k) offsets_[k + 1] += offsets_[k];
  for (const auto& a : activations) vote_offsets_[static_cast<size_t>(a.keypoint) + 1] += table_.occurrences(a.codeword);
  for (size_t k = 0; k < features.size(); ++k) vote_offsets_[k + 1] += vote_offsets_[k];
  by_keypoint_.resize(activations.size());
  std::vector<uint32_t> cursor(offsets_.begin(), offsets_.end() - 1);
  for (const auto& a : activations) by_keypoint_[cursor[static_cast<size_t>(a.keypoint)]++] = a;
  // The activated codewords' votes de-interleaved (the rotation then runs four votes at a time),
  // and the longest of each.
  const size_t stored = table_.vectors.size();
  vx_.reset(new float[stored]);
  vy_.reset(new float[stored]);
  vz_.reset(new float[stored]);
  longest_.assign(static_cast<size_t>(codewords), kNotActivated);
  for (const auto& a : activations) {
    const auto codeword = static_cast<size_t>(a.codeword);
    float& longest = longest_[codeword];
    if (longest != kNotActivated) continue;
    float squared = 0;
    for (uint32_t v = table_.offsets[codeword]; v < table_.offsets[codeword + 1]; ++v) {
      const Eigen::Vector3f& vote = table_.vectors[v];
      vx_[v] = vote.x();
      vy_[v] = vote.y();
      vz_[v] = vote.z();
      squared = std::max(squared, vote.squaredNorm());
      finite_ = finite_ && std::isfinite(vote.squaredNorm());
    }
    longest = std::sqrt(squared);
  }
}

bool VoteCaster::voteBounds(Eigen::Vector3f& lo, Eigen::Vector3f& hi) const {
  if (!finite_) return false;
  lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  hi = -lo;
  bool any = false;
  for (size_t k = 0; k < keypoints(); ++k) {
    float reach = -1;
    for (uint32_t i = offsets_[k]; i < offsets_[k + 1]; ++i) {
      const int codeword = by_keypoint_[i].codeword;
      if (table_.occurrences(codeword) > 0) reach = std::max(reach, longest_[static_cast<size_t>(codeword)]);
    }
    if (reach < 0) continue;  // no votes
    const Eigen::Vector3f extent = features_.lrfs[k].colwise().norm().transpose() * reach;
    const Eigen::Vector3f& o = features_.positions[k];
    if (!(o - extent).allFinite() || !(o + extent).allFinite()) return false;
    lo = lo.cwiseMin(o - extent);
    hi = hi.cwiseMax(o + extent);
    any = true;
  }
  return any;
}

std::vector<Vote> castVotes(const Model& model, int category_index, const Features& features,
                            const std::vector<Activation>& activations, const Strategy& strategy) {
  const VoteCaster caster(model, category_index, features, activations, strategy);
  std::vector<Vote> votes;
  votes.reserve(caster.votes());
  VoteChunk chunk;
  for (size_t k = 0; k < caster.keypoints(); ++k) {
    caster.forEachChunk(k, chunk, [&](const VoteChunk& c) {
      for (uint32_t j = 0; j < c.size; ++j) votes.push_back({c.position(j), c.weight, static_cast<int>(k), category_index});
    });
  }
  return votes;
}

float scoreAt(const std::vector<Vote>& votes, const Eigen::Vector3f& center, float bin_size) {
  float score = 0;
  for (const auto& v : votes) {
    if (insideCube(v.position, center, bin_size / 2)) score += v.weight;
  }
  return score;
}

}  // namespace ism
