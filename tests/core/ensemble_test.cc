// An ensemble's answers: one per object, at the mean of the models' confidences (0 for a model
// without an answer there), a model's draws among them, and the models it refuses to put together.
#include "core/recognition/recognizer.h"

#include <cmath>
#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

#include "core/common/error.h"
#include "core/common/upright_box.h"
#include "core/recognition/ensemble.h"
#include "tests/common/hand_made_votes.h"

namespace ism {
namespace {

using namespace ism::testing;

// A model that finds the hand-made object at a score of 40, calibrated so that its confidence
// there is `confidence`.
Model calibratedAt(const HandMadeObject& o, float confidence) {
  Model m = modelWithVotes(o.votes);
  m.categories[0].box = {0.0f, 10.0f, 10.0f};
  Calibration c;
  c.a = 1.0f;
  c.b = -std::log(40.0f) + std::log(confidence / (1.0f - confidence));
  m.categories[0].calibration = c;
  return m;
}

HandMadeObject object() {
  std::srand(3);
  HandMadeObject o = handMadeObject(Eigen::Vector3f(0.3f, -0.2f, 0.6f), 40, 0, 0.02f);
  o.features.descriptors = DescriptorMatrix::Identity(40, 40);
  return o;
}

// A peak of `confidence` whose upright box (0.5 m cube, gravity frame = scene) is centred at x.
Hypothesis peakAt(float x, float confidence) {
  Hypothesis h;
  h.category = "chair";
  h.confidence = confidence;
  UprightBox box;
  box.center = Eigen::Vector3f(x, 0.0f, 0.25f);
  box.size = Eigen::Vector3f::Constant(0.5f);
  h.box = box.toScene(Eigen::Matrix3f::Identity());
  h.center = box.center;
  return h;
}

TEST(GroupPeaks, OverlappingPeaksOfTheModelsAreOneObjectAtMostOnePerModel) {
  const Eigen::Matrix3f up = Eigen::Matrix3f::Identity();
  // Model 0: a chair at x = 0 and one at x = 3. Model 1: the first chair twice (0.1 m and 0.2 m
  // off: IoU 0.67 and 0.43 with model 0's box), nothing at x = 3.
  const std::vector<std::vector<Hypothesis>> peaks = {{peakAt(0.0f, 0.9f), peakAt(3.0f, 0.4f)},
                                                      {peakAt(0.2f, 0.5f), peakAt(0.1f, 0.3f)}};
  const std::vector<PeakGroup> groups = groupPeaks(peaks, up);
  ASSERT_EQ(groups.size(), 3u);
  // Most confident first: model 0's chair, which model 1's 0.5 joins; model 1's 0.3 overlaps
  // model 0's chair too, but model 1 is already there: an object of its own.
  EXPECT_EQ(groups[0].peak, (std::vector<int>{0, 0}));
  EXPECT_EQ(groups[0].best, 0);
  EXPECT_EQ(groups[1].peak, (std::vector<int>{1, -1}));
  EXPECT_EQ(groups[2].peak, (std::vector<int>{-1, 1}));
  EXPECT_EQ(groups[2].best, 1);
  // Boxes that overlap by less than min_iou are other objects.
  EnsembleParams strict;
  strict.min_iou = 0.7f;
  EXPECT_EQ(groupPeaks(peaks, up, strict).size(), 4u);
}

TEST(GroupPeaks, OneModelHasAGroupPerPeakInOrderOfConfidence) {
  const std::vector<std::vector<Hypothesis>> peaks = {{peakAt(0.0f, 0.2f), peakAt(0.1f, 0.6f)}};
  const std::vector<PeakGroup> groups = groupPeaks(peaks, Eigen::Matrix3f::Identity());
  ASSERT_EQ(groups.size(), 2u);  // overlapping, but one model: merging is suppressOverlaps' work
  EXPECT_EQ(groups[0].peak, (std::vector<int>{1}));
  EXPECT_EQ(groups[1].peak, (std::vector<int>{0}));
}

TEST(Ensemble, OneObjectAtTheMeanOfTheModelsConfidences) {
  const HandMadeObject o = object();
  const Model sure = calibratedAt(o, 0.8f), unsure = calibratedAt(o, 0.4f);
  RecognitionOptions options;
  options.min_confidence = 0.1f;
  const RecognitionResult alone = recognizeFeatures(sure, o.features, options);
  ASSERT_EQ(alone.hypotheses.size(), 1u);
  EXPECT_NEAR(alone.hypotheses[0].confidence, 0.8f, 1e-3f);

  const RecognitionResult same = recognizeEnsembleFeatures({&sure, &sure}, o.features, options, nullptr);
  ASSERT_EQ(same.hypotheses.size(), 1u);
  EXPECT_NEAR(same.hypotheses[0].confidence, 0.8f, 1e-3f);
  EXPECT_EQ(same.hypotheses[0].center, alone.hypotheses[0].center);

  const RecognitionResult both = recognizeEnsembleFeatures({&sure, &unsure}, o.features, options, nullptr);
  ASSERT_EQ(both.hypotheses.size(), 1u);
  EXPECT_NEAR(both.hypotheses[0].confidence, 0.6f, 1e-3f);
  options.min_confidence = 0.65f;  // the mean, not the best model, meets the threshold
  EXPECT_TRUE(recognizeEnsembleFeatures({&sure, &unsure}, o.features, options, nullptr).hypotheses.empty());
}

TEST(Ensemble, AModelWithoutAnAnswerThereCountsAsZero) {
  const HandMadeObject o = object();
  const Model sure = calibratedAt(o, 0.8f), blind = calibratedAt(o, 0.001f);  // below what is looked at
  RecognitionOptions options;
  options.min_confidence = 0.1f;
  const RecognitionResult result = recognizeEnsembleFeatures({&sure, &blind, &blind, &sure}, o.features, options, nullptr);
  ASSERT_EQ(result.hypotheses.size(), 1u);
  EXPECT_NEAR(result.hypotheses[0].confidence, 0.4f, 1e-3f);
}

TEST(Ensemble, AModelsDrawsAnswerWithIt) {
  const HandMadeObject o = object();
  Model drawn = calibratedAt(o, 0.8f);
  drawn.draws = {calibratedAt(o, 0.4f)};
  RecognitionOptions options;
  options.min_confidence = 0.1f;
  const RecognitionResult result = recognizeFeatures(drawn, o.features, options);
  ASSERT_EQ(result.hypotheses.size(), 1u);
  EXPECT_NEAR(result.hypotheses[0].confidence, 0.6f, 1e-3f);
  const Model sure = calibratedAt(o, 0.8f);
  const RecognitionResult with_another = recognizeEnsembleFeatures({&drawn, &sure}, o.features, options);
  ASSERT_EQ(with_another.hypotheses.size(), 1u);
  EXPECT_NEAR(with_another.hypotheses[0].confidence, (0.8f + 0.4f + 0.8f) / 3, 1e-3f);
  options.preset = RecognitionPreset::kSeed;  // the seed's pipeline: one model, its draws left out
  const RecognitionResult seed = recognizeFeatures(drawn, o.features, options);
  const RecognitionResult alone = recognizeFeatures(sure, o.features, options);
  ASSERT_EQ(seed.hypotheses.size(), alone.hypotheses.size());
  for (size_t i = 0; i < seed.hypotheses.size(); ++i) EXPECT_EQ(seed.hypotheses[i].score, alone.hypotheses[i].score);
}

void expectRefused(const std::vector<const Model*>& models, const RecognitionOptions& options, const std::string& says) {
  try {
    recognizeEnsembleFeatures(models, object().features, options, nullptr);
    FAIL() << "no exception; expected one saying " << says;
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidInput);
    EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
  }
}

TEST(Ensemble, ModelsThatCannotAnswerTogetherAreRefused) {
  const HandMadeObject o = object();
  const Model m = calibratedAt(o, 0.8f);
  RecognitionOptions options;
  expectRefused({}, options, "at least one model");
  Model coarser = m;
  coarser.front_end.downsample.leaf_size = 2 * m.front_end.downsample.leaf_size;
  expectRefused({&m, &coarser}, options, "front end");
  Model couch = m;
  couch.categories[0].name = "couch";
  expectRefused({&m, &couch}, options, "categories");
  options.preset = RecognitionPreset::kSeed;
  expectRefused({&m, &m}, options, "default preset");
}

}  // namespace
}  // namespace ism
