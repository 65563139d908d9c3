#pragma once
// Voting: each keypoint's activated codewords cast their stored vectors, turned from the
// keypoint's local reference frame back into the scene, as weighted votes for an object centre.
// The VoteCaster produces them in chunks for the Hough space (hough_space.h), which never
// stores them; castVotes() materialises them for debug output and the leave-one-out scores.
#include <algorithm>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/codebook/codebook.h"
#include "core/common/types.h"
#include "core/model/model.h"

namespace ism {

struct Vote {
  Eigen::Vector3f position;  // where the vote lands (scene frame)
  float weight;
  int keypoint;              // index into Features
  int category;              // index into Model::categories
};

// The frame keypoint k of `features` stores and casts its votes in (rows x, y, z in scene
// coordinates): its LRF, or for VoteFrame::kUpright z = up and x = the horizontal part of its
// surface normal or, where that is nearly vertical, of the direction into its support (the SHOT
// x axis as a last resort). Throws Error(kInvalidInput) for kUpright without the gravity stage's
// output in `features`.
Eigen::Matrix3f voteFrame(const Features& features, size_t k, VoteFrame frame);
std::vector<Eigen::Matrix3f> voteFrames(const Features& features, VoteFrame frame);

// Votes of one category's ISM for already extracted features, materialised (debug output,
// leave-one-out scores); recognition itself accumulates them into a HoughSpace instead.
// Throws Error(kInvalidInput) for an activation outside the features or the vote table.
std::vector<Vote> castVotes(const Model& model, int category_index, const Features& features,
                            const std::vector<Activation>& activations, const Strategy& strategy);

// Summed weight of the votes inside the cube of edge bin_size centred at `center`: the score a
// hypothesis there would get (used for the leave-one-out thresholds).
float scoreAt(const std::vector<Vote>& votes, const Eigen::Vector3f& center, float bin_size);

// The cube of edge 2 * half_edge centred at `center`; scoreAt and the peak search must agree on
// it. Without branches: whether a vote is inside is as good as random.
inline bool insideCube(const Eigen::Vector3f& p, const Eigen::Vector3f& center, float half_edge) {
  const Eigen::Vector3f d = (p - center).cwiseAbs();
  return (d.x() <= half_edge) & (d.y() <= half_edge) & (d.z() <= half_edge);
}

// Votes are produced in chunks of positions in structure-of-arrays layout: the rotation and the
// bin coordinates then run as vector instructions.
constexpr uint32_t kChunk = 256;

struct VoteChunk {
  uint32_t size = 0;
  uint32_t first = 0;  // the vote table's row of position 0
  float weight = 0;
  alignas(16) float x[kChunk], y[kChunk], z[kChunk];
  Eigen::Vector3f position(uint32_t j) const { return {x[j], y[j], z[j]}; }
};

// One category's votes, keypoint by keypoint: the activations grouped per keypoint so that
// keypoints can be split between threads and each keypoint's M (activated codewords) is known.
// Keeps references to its arguments, which must outlive it.
class VoteCaster {
 public:
  // Throws Error(kInvalidInput) for an activation outside the features or the vote table.
  VoteCaster(const Model& model, int category_index, const Features& features,
             const std::vector<Activation>& activations, const Strategy& strategy);

  const CategoryModel& category() const { return category_; }
  const VoteTable& table() const { return table_; }
  const Eigen::Matrix3f& frame(size_t k) const { return frames_[k]; }
  const Features& features() const { return features_; }
  size_t keypoints() const { return features_.size(); }
  size_t votes() const { return votes_; }

  // Bounds that hold every vote: a vote lands at o + R^T v, whose coordinate i lies within
  // |column i of R| * |v| of o's (Cauchy-Schwarz), |v| at most the longest vote of the keypoint's
  // activated codewords. False when nothing votes or a bound is not finite.
  bool voteBounds(Eigen::Vector3f& lo, Eigen::Vector3f& hi) const;

  // How far from keypoint k its votes land along each scene axis at most, as voteBounds bounds
  // them; negative when it casts none.
  Eigen::Vector3f reach(size_t k) const;

  // The index of keypoint k's first vote in the order votes are cast (forEachChunk).
  size_t firstVote(size_t k) const { return vote_offsets_[k]; }

  // Calls f(weight, first, last) for each of keypoint k's activations with votes, in order: its
  // votes are those of table_ rows [first, last), each with that weight. With the height test
  // (VotingParams::height_tolerance) the rows are those of training keypoints at about k's
  // height; the weights spread over all of the codeword's votes, so that the votes a height rules
  // out are lost mass, or with VotingParams::height_normalized over those rows alone.
  template <typename F>
  void forEachActivation(size_t k, F&& f) const {
    const uint32_t begin = offsets_[k], end = offsets_[k + 1];
    const float activated = static_cast<float>(end - begin);
    for (uint32_t i = begin; i < end; ++i) {
      const Activation& a = by_keypoint_[i];
      const auto [first, last] = rows_[i];
      if (first == last) continue;
      float weight = table_.codewordWeight(a.codeword);
      if (weighting_ != VoteWeighting::kCategorization) {
        weight /= activated * static_cast<float>(height_normalized_ ? last - first : table_.occurrences(a.codeword));
        if (weighting_ == VoteWeighting::kActivation) weight *= 1.0f - a.distance / 2.0f;
      }
      f(weight, first, last);
    }
  }

  // Calls f(chunk) for the votes of keypoint k, chunk by chunk.
  template <typename F>
  void forEachChunk(size_t k, VoteChunk& chunk, F&& f) const {
    const Eigen::Matrix3f& r = frames_[k];  // scene -> vote frame; votes go back with its transpose
    const Eigen::Vector3f& o = features_.positions[k];
    forEachActivation(k, [&](float weight, uint32_t first, uint32_t last) {
      chunk.weight = weight;
      for (uint32_t start = first; start < last; start += kChunk) {
        chunk.size = std::min(kChunk, last - start);
        chunk.first = start;
        const float *vx = vx_.get() + start, *vy = vy_.get() + start, *vz = vz_.get() + start;
        // One coordinate per loop: four coefficients, which stay in registers.
        for (uint32_t j = 0; j < chunk.size; ++j) chunk.x[j] = cast(o.x(), r(0, 0), r(1, 0), r(2, 0), vx[j], vy[j], vz[j]);
        for (uint32_t j = 0; j < chunk.size; ++j) chunk.y[j] = cast(o.y(), r(0, 1), r(1, 1), r(2, 1), vx[j], vy[j], vz[j]);
        for (uint32_t j = 0; j < chunk.size; ++j) chunk.z[j] = cast(o.z(), r(0, 2), r(1, 2), r(2, 2), vx[j], vy[j], vz[j]);
        f(static_cast<const VoteChunk&>(chunk));
      }
    });
  }

  // Calls f(weight, v) for each vote v (a row of table_) of keypoint k that lands in the cube of
  // insideCube(center, half_edge), in forEachChunk's order: a chunk's positions are tested without
  // a branch before f sees the few inside. `chunk` is the caller's buffer.
  template <typename F>
  void forEachVoteInCube(size_t k, const Eigen::Vector3f& center, float half_edge, VoteChunk& chunk, F&& f) const {
    forEachChunk(k, chunk, [&](const VoteChunk& votes) {
      alignas(16) uint8_t inside[kChunk];
      for (uint32_t j = 0; j < votes.size; ++j) inside[j] = insideCube(votes.position(j), center, half_edge);
      for (uint32_t j = 0; j < votes.size; ++j) {
        if (inside[j]) f(votes.weight, votes.first + j);
      }
    });
  }

  // Where vote v (a row of table_) of keypoint k lands: the same floats forEachChunk gives it.
  Eigen::Vector3f position(size_t k, uint32_t v) const {
    const Eigen::Matrix3f& r = frames_[k];
    const Eigen::Vector3f& o = features_.positions[k];
    return {cast(o.x(), r(0, 0), r(1, 0), r(2, 0), vx_[v], vy_[v], vz_[v]),
            cast(o.y(), r(0, 1), r(1, 1), r(2, 1), vx_[v], vy_[v], vz_[v]),
            cast(o.z(), r(0, 2), r(1, 2), r(2, 2), vx_[v], vy_[v], vz_[v])};
  }

 private:
  // One coordinate of a vote: o + column of R . v, in this order of operations everywhere.
  static float cast(float o, float r0, float r1, float r2, float vx, float vy, float vz) {
    return o + (r0 * vx + r1 * vy + r2 * vz);
  }

  const CategoryModel& category_;
  const VoteTable& table_;
  const Features& features_;
  VoteWeighting weighting_;
  bool height_normalized_;
  std::vector<uint32_t> offsets_;  // activations of keypoint k: by_keypoint_[offsets_[k] .. offsets_[k+1])
  std::vector<size_t> vote_offsets_;  // votes of keypoint k: [vote_offsets_[k], vote_offsets_[k+1])
  std::vector<Activation> by_keypoint_;
  std::vector<std::pair<uint32_t, uint32_t>> rows_;  // per by_keypoint_ entry: its table_ rows
  std::vector<Eigen::Matrix3f> frames_;              // per keypoint: voteFrame()
  size_t votes_ = 0;
  // The vectors of table_ by coordinate, filled for the activated codewords only.
  std::unique_ptr<float[]> vx_, vy_, vz_;
  static constexpr float kNotActivated = -1;
  std::vector<float> longest_;  // per codeword: its longest vote, or kNotActivated
  bool finite_ = true;          // every activated codeword's votes
};

// The keypoints with at least one vote in the cube of insideCube(center, half_edge), ascending:
// what the seed calls the support of a hypothesis centred there. Keypoints whose votes cannot
// reach the cube are not cast.
std::vector<int> keypointsVotingInto(const VoteCaster& caster, const Eigen::Vector3f& center, float half_edge);

}  // namespace ism
