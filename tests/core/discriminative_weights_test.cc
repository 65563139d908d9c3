// Codeword weights learned from labelled peaks: a codeword that false peaks are made of loses
// votes, one that true peaks are made of keeps them, and nothing gains.
#include "core/training/discriminative_weights.h"

#include <random>

#include <gtest/gtest.h>

#include "core/common/error.h"

namespace ism {
namespace {

// Peaks of one category over three folds: true peaks score higher, the two overlapping; true
// peaks are made of codewords 0 and 1, false ones of 0 and 2 (each half their supporting keypoints).
std::vector<CalibrationSample> peaks(int category) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> high(1.0f, 4.0f), low(0.5f, 2.0f);
  std::vector<CalibrationSample> samples;
  for (int i = 0; i < 240; ++i) {
    CalibrationSample s;
    s.category = category;
    s.positive = i % 4 == 0;
    s.score = s.positive ? high(rng) : low(rng);
    s.support = 10;
    s.fold = i % 3;
    for (int k = 0; k < 10; ++k) s.codewords.push_back(k % 2 == 0 ? 0 : (s.positive ? 1 : 2));
    samples.push_back(s);
  }
  return samples;
}

TEST(DiscriminativeWeights, FalsePeaksCodewordsLoseVotesAndNoneGains) {
  const DiscriminativeWeightParams params;
  const auto factors = learnCodewordFactors(peaks(0), 1, 4, params);
  ASSERT_EQ(factors.size(), 1u);
  const CodewordFactors& f = factors[0];
  ASSERT_EQ(f.factors.size(), 4u);
  EXPECT_LT(f.factors[2], 0.5f);           // what the false peaks are made of
  EXPECT_FLOAT_EQ(f.factors[1], 1.0f);     // what the true ones are made of: no gain past 1
  EXPECT_FLOAT_EQ(f.factors[3], 1.0f);     // never seen: untouched
  for (const float x : f.factors) EXPECT_GE(x, static_cast<float>(params.lowest));
  EXPECT_LT(f.held_out_loss, f.held_out_loss_without);  // the codewords predict the held-out folds
  EXPECT_GT(f.true_peaks_mean, 0.5);       // true peaks keep most of their score
  EXPECT_LE(f.true_peaks_mean, 1.0);
  EXPECT_NE(describeFactors("stool", f).find("1 of 4 codewords lowered"), std::string::npos) << describeFactors("stool", f);
}

TEST(DiscriminativeWeights, CategoriesWithoutBothLabelsKeepTheirWeights) {
  std::vector<CalibrationSample> samples = peaks(0);
  for (auto& s : peaks(1)) {
    if (!s.positive) samples.push_back(s);  // category 1: negatives only
  }
  const auto factors = learnCodewordFactors(samples, 3, 4, {});
  ASSERT_EQ(factors.size(), 3u);
  EXPECT_FALSE(factors[0].factors.empty());
  EXPECT_TRUE(factors[1].factors.empty());  // no true peak
  EXPECT_TRUE(factors[2].factors.empty());  // no peak at all
  EXPECT_NE(describeFactors("table", factors[1]).find("none"), std::string::npos);
  EXPECT_THROW(learnCodewordFactors(samples, 3, 0, {}), Error);
}

TEST(DiscriminativeWeights, AppliedFactorsScaleTheWeightsAndTheThresholds) {
  Model model;
  CategoryModel& category = model.categories.emplace_back();
  category.name = "stool";
  category.global_votes.codeword_weights = {1.0f, 0.5f, 1.0f};
  const ThresholdKey global{CodebookType::kGlobal, ActivationStrategy::kKnn, VoteWeighting::kLocalization};
  const ThresholdKey separated{CodebookType::kSeparated, ActivationStrategy::kKnn, VoteWeighting::kLocalization};
  category.thresholds[global] = 2.0f;
  category.thresholds[separated] = 3.0f;
  CodewordFactors f;
  f.factors = {1.0f, 0.5f, 0.1f};
  f.true_peaks_mean = 0.8;
  applyCodewordFactors(model, {f});
  EXPECT_EQ(category.global_votes.codeword_weights, (std::vector<float>{1.0f, 0.25f, 0.1f}));
  EXPECT_FLOAT_EQ(category.thresholds[global], 1.6f);
  EXPECT_FLOAT_EQ(category.thresholds[separated], 3.0f);  // its own codebook's votes are not weighed
  f.factors = {1.0f, 1.0f};
  EXPECT_THROW(applyCodewordFactors(model, {f}), Error);
}

TEST(RidgeLogistic, FindsTheSlopeThatSeparatesAndRejectsMismatchedInputs) {
  Eigen::MatrixXd x(4, 2);
  x << 1, -2, 1, -1, 1, 1, 1, 2;
  Eigen::VectorXd y(4);
  y << 0, 0, 1, 1;
  const Eigen::VectorXd w = ridgeLogistic(x, y, Eigen::Vector2d(0, 1.0));
  EXPECT_GT(w[1], 0.5);
  EXPECT_NEAR(w[0], 0.0, 1e-6);  // symmetric data: no intercept
  EXPECT_THROW(ridgeLogistic(x, Eigen::VectorXd::Zero(3), Eigen::Vector2d(0, 1)), Error);
}

}  // namespace
}  // namespace ism
