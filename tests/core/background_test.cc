#include "core/training/background.h"

#include <gtest/gtest.h>

#include "core/common/error.h"
#include "tests/common/hand_made_scans.h"

namespace ism {
namespace {

using namespace ism::testing;

TEST(CodewordWeights, AreTheCategorysShareAgainstBackgroundsOfEachSidesTotal) {
  // Category: 3/4 of its keypoints on codeword 0, 1/4 on 2. Background: 1/2 on 1, 1/2 on 2.
  const std::vector<float> w = codewordWeights({30, 0, 10, 0}, {0, 5, 5, 0});
  ASSERT_EQ(w.size(), 4u);
  EXPECT_FLOAT_EQ(w[0], 1.0f);                  // background never activates it
  EXPECT_FLOAT_EQ(w[1], 1.0f);                  // the category casts no votes there
  EXPECT_FLOAT_EQ(w[2], 0.25f / (0.25f + 0.5f));  // background twice as often: a third
  EXPECT_FLOAT_EQ(w[3], 1.0f);
}

TEST(CodewordWeights, WithoutBackgroundEveryCodewordCountsFully) {
  EXPECT_EQ(codewordWeights({3, 1, 0}, {0, 0, 0}), std::vector<float>(3, 1.0f));
  EXPECT_EQ(codewordWeights({0, 0}, {4, 1}), std::vector<float>(2, 1.0f));
}

TEST(CodewordWeights, RejectCountsOfDifferentCodebooks) {
  EXPECT_THROW(codewordWeights({1, 2}, {1, 2, 3}), Error);
}

TEST(ActivationCounts, CountEachKeypointsNearestCodewords) {
  std::vector<TrainingScan> scans = handMadeScans("stool", 1);
  Codebook codebook(scans[0].features.descriptors);  // codeword j = prototype j of the first scan
  std::vector<const TrainingScan*> pointers;
  for (const auto& s : scans) pointers.push_back(&s);
  // Every scan's keypoint j lies ~1e-3 from prototype j: each codeword once per scan.
  EXPECT_EQ(activationCounts(codebook, pointers, {ActivationStrategy::kKnn, 1, 0}),
            std::vector<int>(kKeypoints, kModels * kScansPerModel));
  // Two codewords per keypoint: each codeword still once per scan as the nearest, the second
  // nearest wherever it falls.
  const std::vector<int> two = activationCounts(codebook, pointers, {ActivationStrategy::kKnn, 2, 0});
  ASSERT_EQ(two.size(), static_cast<size_t>(kKeypoints));
  int total = 0;
  for (int n : two) {
    EXPECT_GE(n, kModels * kScansPerModel);
    total += n;
  }
  EXPECT_EQ(total, 2 * kKeypoints * kModels * kScansPerModel);
}

// Background that looks exactly like the category (the same hand-made descriptors) halves every
// codeword's votes, and the leave-one-out thresholds with them; unlike background leaves them.
TEST(TrainFromScans, BackgroundWeighsTheCodewordsAndTheThresholds) {
  TrainingParams params = seedTrainingParams();
  params.global_kmeans.k = kKeypoints;
  params.separated_kmeans.k = kKeypoints;
  params.calibration.enabled = false;
  const std::vector<TrainingScan> scans = handMadeScans("stool", 1);
  const std::vector<TrainingScan> alike = handMadeScans("background", 1), unlike = handMadeScans("background", 2);
  const auto pointers = [](const std::vector<TrainingScan>& v) {
    std::vector<const TrainingScan*> out;
    for (const auto& s : v) out.push_back(&s);
    return out;
  };
  const Model plain = trainFromScans(scans, {"stool"}, params);
  const Model halved = trainFromScans(scans, {"stool"}, params, pointers(alike));
  const Model kept = trainFromScans(scans, {"stool"}, params, pointers(unlike));
  EXPECT_TRUE(plain.categories[0].global_votes.codeword_weights.empty());
  for (CodebookType type : {CodebookType::kGlobal, CodebookType::kSeparated}) {
    SCOPED_TRACE(toString(type));
    const auto& table = type == CodebookType::kGlobal ? halved.categories[0].global_votes : halved.categories[0].own_votes;
    ASSERT_EQ(table.codeword_weights.size(), static_cast<size_t>(kKeypoints));
    for (float w : table.codeword_weights) EXPECT_FLOAT_EQ(w, 0.5f);
    const ThresholdKey lw{type, ActivationStrategy::kKnn, VoteWeighting::kLocalization};
    EXPECT_NEAR(halved.categories[0].thresholds.at(lw), 0.5f * plain.categories[0].thresholds.at(lw), 1e-4f);
  }
  // Random prototypes of another seed: background keypoints fall on some codewords, never on all
  // as often as the category's do.
  const auto& weights = kept.categories[0].global_votes.codeword_weights;
  ASSERT_EQ(weights.size(), static_cast<size_t>(kKeypoints));
  int full = 0;
  for (float w : weights) {
    EXPECT_GT(w, 0.0f);
    EXPECT_LE(w, 1.0f);
    full += w == 1.0f;
  }
  EXPECT_GT(full, 0);
}

}  // namespace
}  // namespace ism
