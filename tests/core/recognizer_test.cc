#include "core/recognition/recognizer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

#include "core/common/error.h"
#include "core/io/cloud_io.h"
#include "core/model/model_file.h"
#include "core/recognition/voting.h"
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

// The sample scene's table (models/sample: a chair drawn up to it hides part of its top) answers
// with the keypoints that have a vote in the bin at its box's centre, in either of the shipped
// model's draws (SuppressionParams::top_support), not those of the peaks it merged; the chair's and
// the couch's answers, and every box, are as without it.
TEST(Recognize, ATablesAnswerIsSupportedByTheKeypointsVotingAtItsBoxsCentre) {
  const Model model = loadModel(std::string(ISM_SOURCE_DIR) + "/models/default/furniture.ismm");
  const Scene scene = loadCloudFile(std::string(ISM_SOURCE_DIR) + "/models/sample/living_room.pcd");
  const Features features = extractFeatures(scene, model.front_end, model.front_end.smoothing.enabled).features;
  RecognitionOptions options;
  const RecognitionResult at_box = recognizeFeatures(model, features, options, &scene);
  options.suppression.top_support = false;
  const RecognitionResult merged = recognizeFeatures(model, features, options, &scene);
  ASSERT_EQ(at_box.hypotheses.size(), 3u);
  ASSERT_EQ(merged.hypotheses.size(), at_box.hypotheses.size());
  int tables = 0;
  for (size_t i = 0; i < at_box.hypotheses.size(); ++i) {
    const Hypothesis& h = at_box.hypotheses[i];
    const Hypothesis& before = merged.hypotheses[i];
    ASSERT_EQ(h.category, before.category);
    EXPECT_TRUE(h.box.center.isApprox(before.box.center)) << h.category;
    if (h.category != "dining_table") {
      EXPECT_EQ(h.support_indices, before.support_indices) << h.category;
      continue;
    }
    ++tables;
    int index = 0;
    while (model.categories[static_cast<size_t>(index)].name != h.category) ++index;
    const float half_edge = model.categories[static_cast<size_t>(index)].bin_size / 2;
    std::vector<char> voting(features.size(), 0);
    std::vector<const Model*> draws{&model};
    for (const Model& draw : model.draws) draws.push_back(&draw);
    ASSERT_EQ(draws.size(), 2u);
    for (const Model* draw : draws) {
      const auto activations = draw->global_codebook->activate(features.descriptors, options.strategy.activation);
      const VoteCaster caster(*draw, index, features, activations, options.strategy);
      for (int k : keypointsVotingInto(caster, h.box.center, half_edge)) voting[static_cast<size_t>(k)] = 1;
    }
    std::vector<int> expected;
    Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
    for (size_t k = 0; k < voting.size(); ++k) {
      if (!voting[k]) continue;
      expected.push_back(static_cast<int>(k));
      centroid += features.positions[k];
    }
    ASSERT_FALSE(expected.empty());
    EXPECT_EQ(h.support_indices, expected);
    EXPECT_EQ(h.support, static_cast<int>(expected.size()));
    EXPECT_TRUE(h.support_centroid.isApprox(centroid / static_cast<float>(expected.size()), 1e-4f));
    EXPECT_NE(h.support_indices, before.support_indices) << "the merged peaks' support";
  }
  EXPECT_EQ(tables, 1);
}

}  // namespace
}  // namespace ism
