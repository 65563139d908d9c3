// The wire library (proto/wire/messages.cc) in process: what the server sends, the clients read
// back unchanged, and what a caller may not send fails naming the field, as INVALID_ARGUMENT.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/common/error.h"
#include "proto/wire/messages.h"
#include "server/status_mapping.h"

namespace ism::testing {
namespace {

Hypothesis sampleHypothesis() {
  Hypothesis h;
  h.category = "dining_chair";
  h.score = 12.5f;
  h.threshold = 4.25f;
  h.confidence = 0.8125f;
  h.center = {1.0f, -2.0f, 0.5f};
  h.box.center = {1.0f, -2.0f, 0.45f};
  h.box.size = {0.5f, 0.55f, 0.9f};
  h.box.rotation = Eigen::Quaternionf(Eigen::AngleAxisf(0.3f, Eigen::Vector3f::UnitZ()));
  h.upright_box = true;
  h.support = 42;
  h.support_centroid = {0.9f, -2.1f, 0.6f};
  h.alternatives = {{"office_chair", 0.5f}, {"couch", 0.125f}};
  h.support_keypoints = {{0.1f, 0.2f, 0.3f}};
  Verification v;
  v.seen = 300;
  v.consistent = 270;
  v.claimed = 4;
  v.object = 2;
  v.yaw = 0.5f;
  v.profile_distance = 0.375f;
  v.center = {1.01f, -2.0f, 0.45f};
  h.verification = v;
  return h;
}

// The status a server call ends with when `convert` throws.
grpc::Status statusOf(const std::function<void()>& convert) {
  try {
    convert();
  } catch (...) {
    return server::statusFromCurrentException();
  }
  return grpc::Status::OK;
}

TEST(WireMessages, ResultsRoundTripWithConfidenceAlternativesAndGravity) {
  RecognitionResult result;
  result.hypotheses = {sampleHypothesis(), sampleHypothesis()};
  result.hypotheses[1].category = "dining_table";
  result.hypotheses[1].upright_box = false;
  result.hypotheses[1].alternatives.clear();
  result.hypotheses[1].verification.reset();
  Gravity gravity;
  gravity.up = Eigen::Vector3f(0.0f, 0.6f, 0.8f);
  gravity.source = UpSource::kFloor;
  gravity.floor_level = -1.25f;
  gravity.floor_points = 5120;
  gravity.wall_points = 900;
  gravity.walls = 2;
  result.gravity = gravity;
  result.input_points = 1000;
  result.keypoints = 77;

  v1::RecognitionResult message;
  wire::resultToProto(result, &message);
  // What other-language clients read: the fields themselves, not only our own reading of them.
  ASSERT_EQ(message.hypotheses_size(), 2);
  EXPECT_FLOAT_EQ(message.hypotheses(0).confidence(), 0.8125f);
  EXPECT_TRUE(message.hypotheses(0).upright_box());
  ASSERT_EQ(message.hypotheses(0).alternatives_size(), 2);
  EXPECT_EQ(message.hypotheses(0).alternatives(1).category(), "couch");
  EXPECT_FLOAT_EQ(message.hypotheses(0).verification().fit(), (270.0f + 10) / (300 + 20));
  EXPECT_EQ(message.hypotheses(0).verification().training_object(), 2);
  EXPECT_FLOAT_EQ(message.hypotheses(0).verification().profile_distance(), 0.375f);
  EXPECT_FALSE(message.hypotheses(1).has_verification());
  EXPECT_EQ(message.gravity().source(), v1::UP_SOURCE_FLOOR);
  EXPECT_TRUE(message.gravity().has_floor_level());

  const RecognitionResult back = wire::resultFromProto(message);
  ASSERT_EQ(back.hypotheses.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    const Hypothesis &a = back.hypotheses[i], &e = result.hypotheses[i];
    EXPECT_EQ(a.category, e.category);
    EXPECT_EQ(a.score, e.score);
    EXPECT_EQ(a.confidence, e.confidence);
    EXPECT_EQ(a.upright_box, e.upright_box);
    EXPECT_EQ(a.center, e.center);
    EXPECT_EQ(a.box.size, e.box.size);
    EXPECT_TRUE(a.box.rotation.coeffs().isApprox(e.box.rotation.coeffs()));
    EXPECT_EQ(a.support, e.support);
    ASSERT_EQ(a.alternatives.size(), e.alternatives.size());
    for (size_t k = 0; k < a.alternatives.size(); ++k) {
      EXPECT_EQ(a.alternatives[k].category, e.alternatives[k].category);
      EXPECT_EQ(a.alternatives[k].confidence, e.alternatives[k].confidence);
    }
    EXPECT_EQ(a.support_keypoints, e.support_keypoints);
    ASSERT_EQ(a.verification.has_value(), e.verification.has_value());
    if (e.verification) {
      EXPECT_EQ(a.verification->seen, e.verification->seen);
      EXPECT_EQ(a.verification->consistent, e.verification->consistent);
      EXPECT_EQ(a.verification->claimed, e.verification->claimed);
      EXPECT_EQ(a.verification->object, e.verification->object);
      EXPECT_EQ(a.verification->yaw, e.verification->yaw);
      EXPECT_EQ(a.verification->profile_distance, e.verification->profile_distance);
      EXPECT_EQ(a.verification->center, e.verification->center);
    }
  }
  ASSERT_TRUE(back.gravity);
  EXPECT_EQ(back.gravity->up, gravity.up);
  EXPECT_EQ(back.gravity->source, UpSource::kFloor);
  EXPECT_EQ(back.gravity->floor_level, gravity.floor_level);
  EXPECT_EQ(back.gravity->floor_points, 5120u);
  EXPECT_EQ(back.gravity->wall_points, 900u);
  EXPECT_EQ(back.gravity->walls, 2);
  EXPECT_EQ(back.input_points, 1000u);
  EXPECT_EQ(back.keypoints, 77u);
}

TEST(WireMessages, GravityWithoutFloorOrAtAllStaysSo) {
  for (const UpSource source : {UpSource::kGiven, UpSource::kAssumed}) {
    RecognitionResult result;
    Gravity gravity;
    gravity.up = Eigen::Vector3f(0, -1, 0);
    gravity.source = source;
    result.gravity = gravity;
    v1::RecognitionResult message;
    wire::resultToProto(result, &message);
    // A floor at level 0 and no floor are different answers: presence, not the value, tells them apart.
    EXPECT_FALSE(message.gravity().has_floor_level()) << toString(source);
    const RecognitionResult back = wire::resultFromProto(message);
    ASSERT_TRUE(back.gravity);
    EXPECT_EQ(back.gravity->source, source);
    EXPECT_FALSE(back.gravity->hasFloor());
    EXPECT_EQ(back.gravity->up, gravity.up);
  }
  v1::RecognitionResult without;
  wire::resultToProto(RecognitionResult{}, &without);
  EXPECT_FALSE(without.has_gravity());
  EXPECT_FALSE(wire::resultFromProto(without).gravity);
}

TEST(WireMessages, AnswerOptionsRoundTripAndUnsetMeansTheDefaults) {
  RecognitionOptions sent;
  sent.preset = RecognitionPreset::kSeed;
  sent.min_confidence = 0.25f;
  sent.one_answer_per_object = false;
  sent.verify = false;
  v1::RecognitionOptions message;
  wire::answerOptionsToProto(sent, &message);
  EXPECT_EQ(message.preset(), v1::RECOGNITION_PRESET_SEED);
  RecognitionOptions got;
  wire::answerOptionsFromProto(message, &got);
  EXPECT_EQ(got.preset, RecognitionPreset::kSeed);
  EXPECT_EQ(got.min_confidence, 0.25f);
  EXPECT_FALSE(got.one_answer_per_object);
  EXPECT_FALSE(got.verify);

  // Unset fields are the defaults service.proto documents, whatever the target held before.
  RecognitionOptions defaults;
  wire::answerOptionsFromProto(v1::RecognitionOptions{}, &got);
  EXPECT_EQ(got.preset, RecognitionPreset::kDefault);
  EXPECT_EQ(got.min_confidence, 0.3f);
  EXPECT_EQ(got.min_confidence, defaults.min_confidence);
  EXPECT_TRUE(got.one_answer_per_object);
  EXPECT_TRUE(got.verify);

  // The bounds themselves are allowed.
  for (const float bound : {0.0f, 0.99f}) {
    message.set_min_confidence(bound);
    wire::answerOptionsFromProto(message, &got);
    EXPECT_EQ(got.min_confidence, bound);
  }
  for (const auto preset : {RecognitionPreset::kDefault, RecognitionPreset::kSeed}) {
    EXPECT_EQ(wire::presetFromProto(wire::toProto(preset)), preset);
  }
  for (const auto source : {UpSource::kGiven, UpSource::kFloor, UpSource::kAssumed}) {
    EXPECT_EQ(wire::upSourceFromProto(wire::toProto(source)), source);
  }
  EXPECT_FALSE(wire::upSourceFromProto(v1::UP_SOURCE_UNSPECIFIED));
}

TEST(WireMessages, UpIsOptionalAndMustBeADirection) {
  v1::Scene scene;
  EXPECT_FALSE(wire::upFromProto(scene));
  wire::toProto(Eigen::Vector3f(0, 0, 3), scene.mutable_up());
  EXPECT_EQ(wire::upFromProto(scene), Eigen::Vector3f(0, 0, 3));  // core normalises it

  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  for (const Eigen::Vector3f& bad : {Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(1e-9f, 0, 0),
                                     Eigen::Vector3f(0, nan, 1), Eigen::Vector3f(inf, 0, 1)}) {
    wire::toProto(bad, scene.mutable_up());
    const grpc::Status status = statusOf([&] { wire::upFromProto(scene); });
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << bad.transpose();
    EXPECT_EQ(status.error_message().rfind("scene.up = (", 0), 0u) << status.error_message();
  }
}

TEST(WireMessages, BadAnswerOptionsNameTheField) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (const float bad : {-0.01f, 0.995f, 1.0f, 7.0f, nan}) {
    v1::RecognitionOptions message;
    message.set_min_confidence(bad);
    RecognitionOptions out;
    const grpc::Status status = statusOf([&] { wire::answerOptionsFromProto(message, &out); });
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << bad;
    EXPECT_NE(status.error_message().find("options.min_confidence = "), std::string::npos) << status.error_message();
  }
  v1::RecognitionOptions message;
  message.set_preset(static_cast<v1::RecognitionPreset>(3));
  RecognitionOptions out;
  const grpc::Status status = statusOf([&] { wire::answerOptionsFromProto(message, &out); });
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(status.error_message().find("options.preset 3 is not supported"), std::string::npos)
      << status.error_message();
}

}  // namespace
}  // namespace ism::testing
