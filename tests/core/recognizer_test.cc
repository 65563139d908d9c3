#include "core/recognition/recognizer.h"

#include <gtest/gtest.h>

#include <cstdlib>

#include "core/common/error.h"
#include "tests/common/hand_made_votes.h"

namespace ism {
namespace {

using testing::HandMadeObject;
using testing::handMadeObject;
using testing::modelWithVotes;
using testing::strategy;

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

TEST(Recognize, EmptySceneIsInvalid) {
  const Model m = modelWithVotes({{Eigen::Vector3f::Zero()}});
  Scene empty;
  EXPECT_THROW(recognize(m, empty, RecognitionOptions{}), Error);
}

}  // namespace
}  // namespace ism
