// The pipeline the server runs stops inside its long loops, not only between its stages: with k
// at every codeword, casting one scene's votes takes seconds, and a caller that is gone (or a
// drain that is over) must not wait for them. In process, on the service tests' model.
#include <gtest/gtest.h>

#include <atomic>

#include "core/common/error.h"
#include "core/model/model_file.h"
#include "core/recognition/recognizer.h"
#include "tests/service/service_fixture.h"

namespace ism::testing {
namespace {

class Cancellation : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    model_ = new Model(loadModel(tinyModelDirectory() + "/default.ismm"));
    scene_ = new SyntheticScene(smallScene(0, 640, 480));
  }
  static void TearDownTestSuite() {
    delete model_;
    delete scene_;
  }

  // Every codeword activated: the most votes this model can cast.
  static RecognitionOptions everyCodeword() {
    RecognitionOptions options;
    options.strategy.activation = model_->trained_knn;
    options.strategy.activation.k = model_->global_codebook->size();
    return options;
  }

  static Model* model_;
  static SyntheticScene* scene_;
};
Model* Cancellation::model_ = nullptr;
SyntheticScene* Cancellation::scene_ = nullptr;

TEST_F(Cancellation, TheStopIsAskedForWhileTheVotesAreCast) {
  RecognitionOptions options = everyCodeword();
  std::atomic<size_t> polls{0};
  options.should_stop = [&] {
    ++polls;
    return false;
  };
  const RecognitionResult result = recognize(*model_, scene_->scene, options);
  ASSERT_GE(result.keypoints, 640u) << "too few keypoints to tell polls in a loop from polls between stages";
  // Between the stages alone it is asked about a dozen times; inside the loops, at least once per
  // few dozen keypoints in each category's voting and peak search.
  EXPECT_GE(polls.load(), result.keypoints / 32) << result.keypoints << " keypoints";
}

TEST_F(Cancellation, AStopSeenInALoopEndsTheRecognitionWithNoResult) {
  RecognitionOptions options = everyCodeword();
  std::atomic<size_t> polls{0};
  options.should_stop = [&] {
    ++polls;
    return false;
  };
  recognize(*model_, scene_->scene, options);
  // Stop once, halfway through the polls (inside a loop), and never again: the stop holds.
  const size_t halfway = polls / 2;
  std::atomic<size_t> count{0};
  options.should_stop = [&] { return ++count == halfway; };
  try {
    recognize(*model_, scene_->scene, options);
    FAIL() << "recognised although told to stop at poll " << halfway;
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kCancelled) << e.what();
  }
}

}  // namespace
}  // namespace ism::testing
