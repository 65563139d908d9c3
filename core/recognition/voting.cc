#include "core/recognition/voting.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/common/error.h"

namespace ism {
namespace {

const VoteTable& votesOf(const CategoryModel& category, CodebookType type) {
  return type == CodebookType::kGlobal ? category.global_votes : category.own_votes;
}

Eigen::Vector3f horizontal(const Eigen::Vector3f& v, const Eigen::Vector3f& up) { return v - up * up.dot(v); }

}  // namespace

Eigen::Matrix3f voteFrame(const Features& features, size_t k, VoteFrame frame) {
  if (frame == VoteFrame::kLrf) return features.lrfs[k];
  if (!features.gravity || features.normals.size() != features.size() ||
      features.support_directions.size() != features.size()) {
    throw Error(ErrorCode::kInvalidInput, "upright vote frames need the features' up, normals and support directions "
                                          "(the front end's gravity stage)");
  }
  const Eigen::Vector3f& up = features.gravity->up;
  // A surface within 60 degrees of vertical faces its way; a flatter one is read from the side
  // its support lies on (a seat's or a table top's edge points into the object).
  constexpr float kSteepEnough = 0.5f;
  Eigen::Vector3f x = horizontal(features.normals[k], up);
  if (x.norm() < kSteepEnough) {
    const Eigen::Vector3f& into = features.support_directions[k];
    const Eigen::Vector3f flat = horizontal(into, up);
    if (flat.norm() > 0.25f * into.norm() && flat.norm() > 1e-4f) x = -flat;
  }
  if (!(x.norm() > 1e-4f)) x = horizontal(features.lrfs[k].row(0).transpose(), up);
  if (!(x.norm() > 1e-6f)) x = horizontal(features.lrfs[k].row(1).transpose(), up);
  x.normalize();
  Eigen::Matrix3f r;
  r.row(0) = x.transpose();
  r.row(1) = up.cross(x).transpose();
  r.row(2) = up.transpose();
  return r;
}

std::vector<Eigen::Matrix3f> voteFrames(const Features& features, VoteFrame frame) {
  if (frame == VoteFrame::kLrf) return features.lrfs;
  std::vector<Eigen::Matrix3f> frames(features.size());
  for (size_t k = 0; k < features.size(); ++k) frames[k] = voteFrame(features, k, frame);
  return frames;
}

VoteCaster::VoteCaster(const Model& model, int category_index, const Features& features,
                       const std::vector<Activation>& activations, const Strategy& strategy)
    : category_(model.categories.at(static_cast<size_t>(category_index))),
      table_(votesOf(category_, strategy.codebook)),
      features_(features),
      weighting_(strategy.weighting),
      height_normalized_(model.voting.height_normalized),
      offsets_(features.size() + 1, 0),
      vote_offsets_(features.size() + 1, 0) {
  if (table_.empty()) return;
  frames_ = voteFrames(features, model.voting.frame);
  const int codewords = static_cast<int>(table_.offsets.size()) - 1;
  const float tolerance = model.voting.height_tolerance;
  const bool by_height = tolerance > 0 && !table_.heights.empty() && features.heights.size() == features.size();
  const auto rowsOf = [&](const Activation& a) {
    uint32_t first = table_.offsets[static_cast<size_t>(a.codeword)];
    uint32_t last = table_.offsets[static_cast<size_t>(a.codeword) + 1];
    if (by_height && first < last) {
      const float h = features.heights[static_cast<size_t>(a.keypoint)];
      const float* heights = table_.heights.data();
      first = static_cast<uint32_t>(std::lower_bound(heights + first, heights + last, h - tolerance) - heights);
      last = std::max(first, static_cast<uint32_t>(std::upper_bound(heights + first, heights + last, h + tolerance) - heights));
    }
    return std::pair<uint32_t, uint32_t>(first, last);
  };
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
  }
  for (size_t k = 0; k < features.size(); ++k) offsets_[k + 1] += offsets_[k];
  by_keypoint_.resize(activations.size());
  rows_.resize(activations.size());
  std::vector<uint32_t> cursor(offsets_.begin(), offsets_.end() - 1);
  for (const auto& a : activations) {
    const uint32_t at = cursor[static_cast<size_t>(a.keypoint)]++;
    by_keypoint_[at] = a;
    rows_[at] = rowsOf(a);
    const uint32_t cast = rows_[at].second - rows_[at].first;
    votes_ += cast;
    vote_offsets_[static_cast<size_t>(a.keypoint) + 1] += cast;
  }
  for (size_t k = 0; k < features.size(); ++k) vote_offsets_[k + 1] += vote_offsets_[k];
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

Eigen::Vector3f VoteCaster::reach(size_t k) const {
  float longest = -1;
  for (uint32_t i = offsets_[k]; i < offsets_[k + 1]; ++i) {
    const int codeword = by_keypoint_[i].codeword;
    if (table_.occurrences(codeword) > 0) longest = std::max(longest, longest_[static_cast<size_t>(codeword)]);
  }
  if (longest < 0) return Eigen::Vector3f::Constant(-1);
  return frames_[k].colwise().norm().transpose() * longest;
}

bool VoteCaster::voteBounds(Eigen::Vector3f& lo, Eigen::Vector3f& hi) const {
  if (!finite_) return false;
  lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  hi = -lo;
  bool any = false;
  for (size_t k = 0; k < keypoints(); ++k) {
    const Eigen::Vector3f extent = reach(k);
    if (extent.x() < 0) continue;  // no votes
    const Eigen::Vector3f& o = features_.positions[k];
    if (!(o - extent).allFinite() || !(o + extent).allFinite()) return false;
    lo = lo.cwiseMin(o - extent);
    hi = hi.cwiseMax(o + extent);
    any = true;
  }
  return any;
}

std::vector<int> keypointsVotingInto(const VoteCaster& caster, const Eigen::Vector3f& center, float half_edge) {
  std::vector<int> keypoints;
  VoteChunk chunk;
  for (size_t k = 0; k < caster.keypoints(); ++k) {
    const Eigen::Vector3f extent = caster.reach(k);
    if (extent.x() < 0) continue;
    const Eigen::Vector3f gap = (caster.features().positions[k] - center).cwiseAbs();
    // A millimetre more for the floats' rounding; a reach that is not finite casts its votes and
    // leaves the test to insideCube.
    if (extent.allFinite() && (gap.array() > extent.array() + (half_edge + 1e-3f)).any()) continue;
    bool inside = false;
    caster.forEachVoteInCube(k, center, half_edge, chunk, [&](float, uint32_t) { inside = true; });
    if (inside) keypoints.push_back(static_cast<int>(k));
  }
  return keypoints;
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
