#include "core/recognition/voting.h"

#include <gtest/gtest.h>

#include <numeric>
#include <random>

#include "core/common/error.h"
#include "core/recognition/hough_space.h"
#include "tests/common/hand_made_votes.h"

namespace ism {
namespace {

using namespace ism::testing;

TEST(CastVotes, VotesRotatedBackLandOnTheCentre) {
  const Eigen::Vector3f center(1.0f, -2.0f, 0.5f);
  const HandMadeObject o = handMadeObject(center, 50);
  const Model m = modelWithVotes(o.votes);
  const auto votes = castVotes(m, 0, o.features, o.activations, strategy(VoteWeighting::kCategorization));
  ASSERT_EQ(votes.size(), 50u);
  for (const auto& v : votes) {
    EXPECT_LT((v.position - center).norm(), 1e-5f);
    EXPECT_EQ(v.weight, 1.0f);
    EXPECT_EQ(v.category, 0);
  }
  const auto peaks = HoughSpace(m, 0, o.features, o.activations, strategy(VoteWeighting::kCategorization)).findPeaks(10.0f);
  ASSERT_EQ(peaks.size(), 1u);
  EXPECT_LT((peaks[0].center - center).norm(), 1e-5f);
  EXPECT_FLOAT_EQ(peaks[0].score, 50.0f);
  EXPECT_EQ(peaks[0].support, 50);
  EXPECT_FLOAT_EQ(peaks[0].score, scoreAt(votes, peaks[0].center, m.categories[0].bin_size));
}

TEST(CastVotes, LocalizationWeightsOfAKeypointSumToOneAndActivationWeightsAreSmaller) {
  Features f;
  f.positions = {Eigen::Vector3f::Zero()};
  f.lrfs = {Eigen::Matrix3f::Identity()};
  const std::vector<Eigen::Vector3f> three(3, Eigen::Vector3f::UnitX()), five(5, Eigen::Vector3f::UnitY());
  const Model m = modelWithVotes({three, five});
  const std::vector<Activation> activations{{0, 0, 0.3f}, {0, 1, 0.6f}};
  const auto lw = castVotes(m, 0, f, activations, strategy(VoteWeighting::kLocalization));
  const auto aw = castVotes(m, 0, f, activations, strategy(VoteWeighting::kActivation));
  ASSERT_EQ(lw.size(), 8u);
  ASSERT_EQ(aw.size(), 8u);
  const auto sum = [](const std::vector<Vote>& v) {
    return std::accumulate(v.begin(), v.end(), 0.0f, [](float s, const Vote& x) { return s + x.weight; });
  };
  EXPECT_NEAR(sum(lw), 1.0f, 1e-6f);
  EXPECT_FLOAT_EQ(lw[0].weight, 1.0f / (2 * 3));
  EXPECT_FLOAT_EQ(lw[3].weight, 1.0f / (2 * 5));
  for (size_t i = 0; i < aw.size(); ++i) EXPECT_LT(aw[i].weight, lw[i].weight);
  EXPECT_FLOAT_EQ(aw[0].weight, (1 - 0.3f / 2) / (2 * 3));
}

// Codewords weighed against background (background.h) scale their votes under every weighting.
TEST(CastVotes, CodewordWeightsScaleTheirVotes) {
  Features f;
  f.positions = {Eigen::Vector3f::Zero()};
  f.lrfs = {Eigen::Matrix3f::Identity()};
  const std::vector<Eigen::Vector3f> three(3, Eigen::Vector3f::UnitX()), five(5, Eigen::Vector3f::UnitY());
  Model m = modelWithVotes({three, five});
  m.categories[0].global_votes.codeword_weights = {0.5f, 0.25f};
  const std::vector<Activation> activations{{0, 0, 0.3f}, {0, 1, 0.6f}};
  const auto cw = castVotes(m, 0, f, activations, strategy(VoteWeighting::kCategorization));
  const auto lw = castVotes(m, 0, f, activations, strategy(VoteWeighting::kLocalization));
  ASSERT_EQ(lw.size(), 8u);
  EXPECT_FLOAT_EQ(cw[0].weight, 0.5f);
  EXPECT_FLOAT_EQ(cw[3].weight, 0.25f);
  EXPECT_FLOAT_EQ(lw[0].weight, 0.5f / (2 * 3));
  EXPECT_FLOAT_EQ(lw[3].weight, 0.25f / (2 * 5));
}

// The height test casts only the votes of training keypoints near the keypoint's height; the
// others are lost mass, or with height_normalized the keypoint's weight goes to those it casts.
TEST(CastVotes, TheHeightTestLosesOtherHeightsMassUnlessNormalized) {
  Features f;
  f.positions = {Eigen::Vector3f::Zero()};
  f.lrfs = {Eigen::Matrix3f::Identity()};
  f.heights = {0.5f};
  // Training keypoints at 0.1, 0.12, 0.48 and 0.9 m (ascending, as packVotes stores them).
  Model m = modelWithVotes({{Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitY(),
                             Eigen::Vector3f::UnitZ()}});
  m.categories[0].global_votes.heights = {0.1f, 0.12f, 0.48f, 0.9f};
  m.voting.height_tolerance = 0.1f;
  const std::vector<Activation> activations{{0, 0, 0.2f}};
  const auto lost = castVotes(m, 0, f, activations, strategy(VoteWeighting::kLocalization));
  ASSERT_EQ(lost.size(), 1u);
  EXPECT_LT((lost[0].position - Eigen::Vector3f::UnitY()).norm(), 1e-6f);
  EXPECT_FLOAT_EQ(lost[0].weight, 1.0f / 4);
  m.voting.height_normalized = true;
  const auto normalized = castVotes(m, 0, f, activations, strategy(VoteWeighting::kLocalization));
  ASSERT_EQ(normalized.size(), 1u);
  EXPECT_FLOAT_EQ(normalized[0].weight, 1.0f);
  // A keypoint at a height no training keypoint had casts nothing either way.
  f.heights = {0.7f};
  EXPECT_TRUE(castVotes(m, 0, f, activations, strategy(VoteWeighting::kLocalization)).empty());
}

TEST(CastVotes, RejectsActivationsOutsideTheTable) {
  const HandMadeObject o = handMadeObject(Eigen::Vector3f::Zero(), 2);
  const Model m = modelWithVotes(o.votes);
  EXPECT_THROW(castVotes(m, 0, o.features, {{0, 7, 0.0f}}, strategy(VoteWeighting::kCategorization)), Error);
}

// The votes of a keypoint in a cube, as the upright box reads them: exactly those whose landing
// place is inside, in order, across the chunks a long codeword is tested in.
TEST(VoteCaster, VotesInACubeAreThoseLandingInsideAcrossChunks) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> coordinate(-1.0f, 1.0f);
  std::vector<std::vector<Eigen::Vector3f>> votes(2);
  for (int i = 0; i < 3 * static_cast<int>(kChunk) + 17; ++i) {
    votes[i % 5 == 0 ? 1 : 0].emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
  }
  const Model m = modelWithVotes(votes);
  Features f;
  f.positions = {Eigen::Vector3f(0.3f, -0.2f, 1.0f)};
  f.lrfs = {Eigen::AngleAxisf(0.7f, Eigen::Vector3f(1, 2, 3).normalized()).toRotationMatrix()};
  const std::vector<Activation> activations{{0, 0, 0.1f}, {0, 1, 0.2f}};
  const VoteCaster caster(m, 0, f, activations, strategy(VoteWeighting::kLocalization));
  const Eigen::Vector3f centre(0.5f, 0.0f, 1.2f);
  const float half_edge = 0.4f;
  std::vector<std::pair<float, uint32_t>> expected, got;
  caster.forEachActivation(0, [&](float w, uint32_t first, uint32_t last) {
    for (uint32_t v = first; v < last; ++v) {
      if (insideCube(caster.position(0, v), centre, half_edge)) expected.emplace_back(w, v);
    }
  });
  VoteChunk chunk;
  caster.forEachVoteInCube(0, centre, half_edge, chunk, [&](float w, uint32_t v) { got.emplace_back(w, v); });
  ASSERT_GT(expected.size(), 20u);
  ASSERT_LT(expected.size(), votes[0].size() / 2);
  EXPECT_EQ(got, expected);
}

// The seed's support of a hypothesis at a place: the keypoints with at least one vote in the bin
// there, found by casting every keypoint's votes (keypointsVotingInto skips those that cannot reach
// the bin), in ascending order; none where nothing lands.
TEST(VoteCaster, TheKeypointsVotingIntoABinAreThoseWithAVoteThere) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> coordinate(-0.6f, 0.6f), place(-2.0f, 2.0f);
  std::vector<std::vector<Eigen::Vector3f>> votes(3);
  for (auto& codeword : votes) {
    for (int i = 0; i < 40; ++i) codeword.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
  }
  const Model m = modelWithVotes(votes);
  Features f;
  std::vector<Activation> activations;
  for (int k = 0; k < 200; ++k) {
    f.positions.emplace_back(place(rng), place(rng), place(rng) / 4);
    f.lrfs.push_back(Eigen::AngleAxisf(0.1f * static_cast<float>(k), Eigen::Vector3f(1, 1, 2).normalized()).toRotationMatrix());
    activations.push_back({k, k % 3, 0.1f});
  }
  const VoteCaster caster(m, 0, f, activations, strategy(VoteWeighting::kLocalization));
  const Eigen::Vector3f centre(0.2f, -0.4f, 0.1f);
  const float half_edge = 0.15f;
  std::vector<int> expected;
  for (size_t k = 0; k < f.size(); ++k) {
    bool inside = false;
    caster.forEachActivation(k, [&](float, uint32_t first, uint32_t last) {
      for (uint32_t v = first; v < last; ++v) inside = inside || insideCube(caster.position(k, v), centre, half_edge);
    });
    if (inside) expected.push_back(static_cast<int>(k));
  }
  ASSERT_GT(expected.size(), 5u);
  ASSERT_LT(expected.size(), f.size() / 2);
  EXPECT_EQ(keypointsVotingInto(caster, centre, half_edge), expected);
  EXPECT_TRUE(keypointsVotingInto(caster, Eigen::Vector3f(20, 0, 0), half_edge).empty());
}

}  // namespace
}  // namespace ism
