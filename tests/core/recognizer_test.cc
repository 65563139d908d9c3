#include "core/recognition/recognizer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

#include "core/common/error.h"
#include "tests/common/hand_made_votes.h"

namespace ism {
namespace {

using namespace ism::testing;

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

TEST(Recognize, FeaturesOfAnObjectGiveItsHypothesisAtTheModelsThreshold) {
  std::srand(3);
  const Eigen::Vector3f center(0.3f, -0.2f, 0.6f);
  HandMadeObject o = handMadeObject(center, 40, 0, 0.02f);
  Model m = modelWithVotes(o.votes);
  m.categories[0].box = {0.0f, 10.0f, 10.0f};  // the random keypoints' box: up to 1.4 m long
  o.features.descriptors = DescriptorMatrix::Identity(40, 40);  // keypoint i activates codeword i
  RecognitionOptions options;  // global 1-NN LW: each keypoint's one vote weighs 1
  options.return_keypoints = true;
  // Without a calibration, confidence is 1 - 2^-(score / threshold): 0.5 at the model's threshold.
  options.min_confidence = 0.5f;
  const RecognitionResult result = recognizeFeatures(m, o.features, options);
  EXPECT_EQ(result.keypoints, 40u);
  ASSERT_EQ(result.hypotheses.size(), 1u);
  const Hypothesis& h = result.hypotheses[0];
  EXPECT_LT((h.center - center).norm(), 0.03f);
  EXPECT_NEAR(h.score, 40.0f, 1e-4f);
  EXPECT_EQ(h.threshold, 0.5f);  // the model's
  EXPECT_EQ(h.support_keypoints.size(), 40u);
  std::vector<std::string> stages;
  for (const auto& [name, ms] : result.timings.stages) stages.push_back(name);
  EXPECT_EQ(stages, (std::vector<std::string>{"activate", "vote", "hypotheses", "select"}));
  options.min_score = 40.5f;
  EXPECT_TRUE(recognizeFeatures(m, o.features, options).hypotheses.empty());
}

TEST(Recognize, UnorganizedScenesTakeTheCloudCalibration) {
  std::srand(3);
  HandMadeObject o = handMadeObject(Eigen::Vector3f(0.3f, -0.2f, 0.6f), 40, 0, 0.02f);
  Model m = modelWithVotes(o.votes);
  m.categories[0].box = {0.0f, 10.0f, 10.0f};
  o.features.descriptors = DescriptorMatrix::Identity(40, 40);
  Calibration frames;  // score 40 -> confidence 0.5
  frames.a = 1.0f;
  frames.b = -std::log(40.0f);
  Calibration clouds = frames;  // -> 0.88
  clouds.b += 2.0f;
  m.categories[0].calibration = frames;
  RecognitionOptions options;
  options.min_confidence = 0.1f;
  const auto confidence = [&](bool organized) {
    o.features.organized = organized;
    const RecognitionResult result = recognizeFeatures(m, o.features, options);
    return result.hypotheses.empty() ? -1.0f : result.hypotheses[0].confidence;
  };
  EXPECT_NEAR(confidence(false), 0.5f, 1e-3f) << "a model without a cloud calibration uses its one calibration";
  m.categories[0].cloud_calibration = clouds;
  EXPECT_NEAR(confidence(true), 0.5f, 1e-3f);
  EXPECT_NEAR(confidence(false), 1.0f / (1.0f + std::exp(-2.0f)), 1e-3f);
}

// A cloud without pose whose points surround its origin (a fused map) is looked at from its
// middle (core/gravity/viewpoint.h); a single view keeps its sensor.
TEST(Recognize, AMapIsLookedAtFromItsMiddle) {
  const Model m = modelWithVotes({{Eigen::Vector3f::Zero()}});
  Scene map;
  map.source = "map";
  for (int i = 0; i < 400; ++i) {
    const float a = 0.0157f * static_cast<float>(i);  // a ring of wall 2 m around the origin
    for (float z : {0.0f, 0.5f, 1.0f}) map.cloud->push_back(PointT(2 * std::cos(a), 2 * std::sin(a), z));
  }
  map.up = Eigen::Vector3f::UnitZ();
  const RecognitionResult result = recognize(m, map, RecognitionOptions{});
  EXPECT_NEAR(result.viewpoint.z(), 1.5f, 1e-3f);
  EXPECT_LT(result.viewpoint.head<2>().norm(), 0.1f);
  Scene view = map;
  view.sensor_origin = Eigen::Vector3f(0, 0, 0.7f);
  EXPECT_EQ(recognize(m, view, RecognitionOptions{}).viewpoint, view.sensor_origin);
}

TEST(Recognize, EmptySceneIsInvalid) {
  const Model m = modelWithVotes({{Eigen::Vector3f::Zero()}});
  Scene empty;
  EXPECT_THROW(recognize(m, empty, RecognitionOptions{}), Error);
}

}  // namespace
}  // namespace ism
