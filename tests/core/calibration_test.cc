// The calibration's logistic fit: the confidence follows whichever of score and verification fit
// tells positives from negatives.
#include "core/training/calibration.h"

#include <random>

#include <gtest/gtest.h>

#include "core/common/error.h"

namespace ism {
namespace {

TEST(FitCalibration, TheFitDecidesWhereTheScoreCannot) {
  // Scores drawn alike for both; positives fit the scene (0.7-1.0), negatives do not (0.1-0.6).
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> score(0.05f, 2.0f), good(0.7f, 1.0f), bad(0.1f, 0.6f);
  std::vector<CalibrationSample> samples;
  for (int i = 0; i < 400; ++i) {
    const bool positive = i % 4 == 0;
    samples.push_back({0, score(rng), 10, positive, positive ? good(rng) : bad(rng)});
  }
  const Calibration fit = fitCalibration(samples);
  EXPECT_GT(fit.d, 5.0f);
  EXPECT_GT(fit.confidence(0.5f, 10, 0.9f), 0.9f);
  EXPECT_LT(fit.confidence(0.5f, 10, 0.3f), 0.1f);
  EXPECT_EQ(fit.positives, 100);
  EXPECT_EQ(fit.negatives, 300);
}

TEST(FitCalibration, UnverifiedSamplesLeaveTheFitOutOfIt) {
  // Every sample unverified (fit 0.5): the score alone separates, and the fit term cannot matter.
  std::vector<CalibrationSample> samples;
  for (int i = 0; i < 200; ++i) {
    const bool positive = i % 2 == 0;
    samples.push_back({0, positive ? 1.0f + 0.01f * static_cast<float>(i) : 0.1f + 0.001f * static_cast<float>(i), 8,
                       positive, 0.5f});
  }
  const Calibration fit = fitCalibration(samples);
  EXPECT_GT(fit.a + fit.c, 0.0f);
  EXPECT_GT(fit.confidence(2.0f, 8), 0.9f);
  EXPECT_LT(fit.confidence(0.15f, 8), 0.1f);
  EXPECT_NEAR(fit.confidence(0.5f, 8, 0.5f), fit.confidence(0.5f, 8), 1e-6f);
}

TEST(FitCalibration, NeedsBothKinds) {
  EXPECT_THROW(fitCalibration({{0, 1.0f, 3, true, 0.9f}}), Error);
}

}  // namespace
}  // namespace ism
