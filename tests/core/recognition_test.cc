#include "core/recognition/recognizer.h"

#include <gtest/gtest.h>

#include <numeric>

#include "core/common/error.h"

namespace ism {
namespace {

// A one-category model over a global codebook of `codewords` 4-d codewords whose vote table
// holds `votes[i]` under codeword i.
Model modelWithVotes(const std::vector<std::vector<Eigen::Vector3f>>& votes, float bin_size = 0.1f) {
  Model m;
  m.global_codebook = Codebook(DescriptorMatrix::Identity(static_cast<Eigen::Index>(votes.size()), 4));
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

Strategy strategy(VoteWeighting w) {
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

HandMadeObject handMadeObject(const Eigen::Vector3f& center, int keypoints, int first_keypoint = 0) {
  HandMadeObject o;
  for (int i = 0; i < keypoints; ++i) {
    const Eigen::Vector3f p = center + 0.4f * Eigen::Vector3f::Random();
    const Eigen::Matrix3f lrf = Eigen::Quaternionf::UnitRandom().toRotationMatrix().transpose();
    o.features.positions.push_back(p);
    o.features.lrfs.push_back(lrf);
    o.votes.push_back({lrf * (center - p)});
    o.activations.push_back({first_keypoint + i, first_keypoint + i, 0.0f});
  }
  return o;
}

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
  const auto peaks = findPeaks(votes, o.features, m.categories[0], 10.0f);
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

TEST(CastVotes, RejectsActivationsOutsideTheTable) {
  const HandMadeObject o = handMadeObject(Eigen::Vector3f::Zero(), 2);
  const Model m = modelWithVotes(o.votes);
  EXPECT_THROW(castVotes(m, 0, o.features, {{0, 7, 0.0f}}, strategy(VoteWeighting::kCategorization)), Error);
}

TEST(FindPeaks, TwoSeparatedClustersGiveTwoHypotheses) {
  const Eigen::Vector3f a(0, 0, 0.5f), b(1.5f, 0.3f, 0.5f);
  HandMadeObject first = handMadeObject(a, 30), second = handMadeObject(b, 20, 30);
  Features f = first.features;
  f.positions.insert(f.positions.end(), second.features.positions.begin(), second.features.positions.end());
  f.lrfs.insert(f.lrfs.end(), second.features.lrfs.begin(), second.features.lrfs.end());
  auto table = first.votes;
  table.insert(table.end(), second.votes.begin(), second.votes.end());
  auto activations = first.activations;
  activations.insert(activations.end(), second.activations.begin(), second.activations.end());
  const Model m = modelWithVotes(table);
  auto votes = castVotes(m, 0, f, activations, strategy(VoteWeighting::kCategorization));
  // Spread the votes a little so the peak is a real cluster, not one point.
  for (auto& v : votes) v.position += 0.02f * Eigen::Vector3f::Random();
  const auto peaks = findPeaks(votes, f, m.categories[0], 5.0f);
  ASSERT_EQ(peaks.size(), 2u);
  EXPECT_LT((peaks[0].center - a).norm(), 0.05f);
  EXPECT_LT((peaks[1].center - b).norm(), 0.05f);
  EXPECT_GE(peaks[0].score, peaks[1].score);
  EXPECT_EQ(peaks[1].support, 20);
  for (const auto& p : peaks) {
    EXPECT_FLOAT_EQ(p.score, scoreAt(votes, p.center, m.categories[0].bin_size));
    EXPECT_GT(p.score, p.threshold);
  }
  // A threshold above the weaker cluster keeps only the stronger one.
  EXPECT_EQ(findPeaks(votes, f, m.categories[0], 25.0f).size(), 1u);
}

TEST(FindPeaks, NoVotesNoHypotheses) {
  const Model m = modelWithVotes({{Eigen::Vector3f::Zero()}});
  EXPECT_TRUE(findPeaks({}, Features{}, m.categories[0], 0.0f).empty());
}

TEST(BoxSelection, FitsARotatedBoxAndAppliesTheLimits) {
  const Eigen::Matrix3f rotation = Eigen::AngleAxisf(0.7f, Eigen::Vector3f(0.2f, 0.3f, 1.0f).normalized()).toRotationMatrix();
  const Eigen::Vector3f center(2, 1, 0.4f), half(0.5f, 0.25f, 0.1f);
  std::vector<Eigen::Vector3f> corners;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3f s((i & 1) ? 1.f : -1.f, (i & 2) ? 1.f : -1.f, (i & 4) ? 1.f : -1.f);
    corners.push_back(center + rotation * s.cwiseProduct(half));
  }
  const OrientedBox box = fitOrientedBox(corners);
  EXPECT_LT((box.center - center).norm(), 1e-4f);
  Eigen::Vector3f size = box.size;
  std::sort(size.data(), size.data() + 3);
  EXPECT_TRUE(size.isApprox(Eigen::Vector3f(0.2f, 0.5f, 1.0f), 1e-4f)) << size.transpose();
  EXPECT_NEAR(box.volume(), 0.1f, 1e-4f);

  BoxStats stats{0.05f, 0.2f, 1.2f};
  EXPECT_TRUE(passesBoxSelection(box, stats));
  stats.max_edge = 0.9f;  // longest edge too long
  EXPECT_FALSE(passesBoxSelection(box, stats));
  stats = {0.15f, 0.2f, 1.2f};  // too small
  EXPECT_FALSE(passesBoxSelection(box, stats));
  stats = {0.01f, 0.05f, 1.2f};  // too large
  EXPECT_FALSE(passesBoxSelection(box, stats));
}

Scene onePointScene() {
  Scene s;
  s.cloud->push_back(PointT());
  s.source = "test scene";
  return s;
}

TEST(Recognize, UnknownCategoryIsNotFound) {
  const Model m = modelWithVotes({{Eigen::Vector3f::Zero()}});
  RecognitionOptions options;
  options.categories = {"bed"};
  try {
    recognize(m, onePointScene(), options);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kNotFound);
    EXPECT_NE(std::string(e.what()).find("'bed'"), std::string::npos) << e.what();
  }
}

TEST(Recognize, StrategyTheModelLacksIsInvalid) {
  const Model m = modelWithVotes({{Eigen::Vector3f::Zero()}});
  RecognitionOptions options;
  options.strategy.codebook = CodebookType::kSeparated;
  try {
    recognize(m, onePointScene(), options);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidInput);
    EXPECT_NE(std::string(e.what()).find("separated"), std::string::npos) << e.what();
  }
  options.strategy = strategy(VoteWeighting::kActivation);  // no threshold trained for it
  EXPECT_THROW(recognize(m, onePointScene(), options), Error);
}

TEST(Recognize, EmptySceneIsInvalid) {
  const Model m = modelWithVotes({{Eigen::Vector3f::Zero()}});
  Scene empty;
  EXPECT_THROW(recognize(m, empty, RecognitionOptions{}), Error);
}

}  // namespace
}  // namespace ism
