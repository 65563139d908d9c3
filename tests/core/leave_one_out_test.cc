#include "core/training/leave_one_out.h"

#include <gtest/gtest.h>

#include <cmath>

#include "tests/common/hand_made_scans.h"

namespace ism {
namespace {

using testing::handMadeScans;
using testing::kKeypoints;
using testing::kModels;
using testing::kScansPerModel;

// The hand-made scans' codebook: the first scan's descriptors, one codeword per prototype (the
// others lie ~1e-3 from theirs), so 1-NN activates codeword j for keypoint j of every scan.
struct HandMadeCategory {
  std::vector<TrainingScan> scans;
  std::vector<const TrainingScan*> pointers;
  Codebook codebook;
  std::vector<TrainingVote> votes;
};

HandMadeCategory handMadeCategory(uint32_t seed, int odd_model = -1) {
  HandMadeCategory c;
  c.scans = handMadeScans("stool", seed, odd_model);
  for (const auto& s : c.scans) c.pointers.push_back(&s);
  c.codebook = Codebook(c.scans[0].features.descriptors);
  c.votes = trainingVotes(c.pointers, c.codebook);
  return c;
}

const std::vector<ActivationParams> kActivations{{ActivationStrategy::kKnn, 1, 0.25f},
                                                 {ActivationStrategy::kCutoff, 1, 0.25f}};

TEST(LeaveOneOut, IdenticalModelsGiveEveryHeldOutScanTheOtherModelsVotes) {
  const HandMadeCategory c = handMadeCategory(1);
  const LeaveOneOutInput input{"stool", CodebookType::kGlobal, c.codebook, c.votes, c.pointers, kModels, 0.1f};
  const std::vector<LeaveOneOutThreshold> thresholds = leaveOneOutThresholds(input, kActivations, 0.5f, 2);
  ASSERT_EQ(thresholds.size(), 6u);
  // Activation by activation, then CW, LW, AW.
  EXPECT_EQ(thresholds[0].key, (ThresholdKey{CodebookType::kGlobal, ActivationStrategy::kKnn,
                                             VoteWeighting::kCategorization}));
  EXPECT_EQ(thresholds[5].key, (ThresholdKey{CodebookType::kGlobal, ActivationStrategy::kCutoff,
                                             VoteWeighting::kActivation}));
  for (size_t a = 0; a < 2; ++a) {
    const LeaveOneOutThreshold &cw = thresholds[a * 3], &lw = thresholds[a * 3 + 1], &aw = thresholds[a * 3 + 2];
    // Every held-out scan: kKeypoints codewords, each with (kModels - 1) * kScansPerModel votes at the centre.
    EXPECT_NEAR(cw.mean, kKeypoints * (kModels - 1) * kScansPerModel, 1e-3);
    EXPECT_NEAR(cw.std, 0.0, 1e-3);
    EXPECT_NEAR(cw.threshold, cw.mean, 1e-3);
    EXPECT_FALSE(cw.floored);
    EXPECT_NEAR(lw.threshold, kKeypoints, 1e-3f);  // each keypoint's votes weigh 1 in all
    EXPECT_LT(aw.threshold, lw.threshold);
    EXPECT_GT(aw.threshold, 0.99f * lw.threshold);
  }
}

// Held out, models 0 and 1 get the votes of the other's 4 scans at their centre, model 2 none:
// CW scores 48, 48, 0 per scan (4 scans each), mean 32, std sqrt(512). mean - std = 9.4 is
// below half the mean: floored to 16 at a floor of 0.5, kept at a floor of 0.
TEST(LeaveOneOut, ThresholdOfDissimilarModelsIsFlooredAtAFractionOfTheMean) {
  const HandMadeCategory c = handMadeCategory(3, 2);
  const LeaveOneOutInput input{"stool", CodebookType::kSeparated, c.codebook, c.votes, c.pointers, kModels, 0.1f};
  const double mean = 2.0 / 3 * kKeypoints * kScansPerModel, std = std::sqrt(512.0);
  const LeaveOneOutThreshold floored = leaveOneOutThresholds(input, kActivations, 0.5f, 1)[0];
  EXPECT_EQ(floored.key.codebook, CodebookType::kSeparated);
  EXPECT_NEAR(floored.mean, mean, 1e-3);
  EXPECT_NEAR(floored.std, std, 1e-3);
  EXPECT_TRUE(floored.floored);
  EXPECT_NEAR(floored.threshold, 0.5 * mean, 1e-3);
  const LeaveOneOutThreshold seed_rule = leaveOneOutThresholds(input, kActivations, 0.0f, 1)[0];
  EXPECT_FALSE(seed_rule.floored);
  EXPECT_NEAR(seed_rule.threshold, mean - std, 1e-3);
}

}  // namespace
}  // namespace ism
