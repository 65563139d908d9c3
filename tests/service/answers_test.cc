// What the service answers under each preset, and the up it answers in: the real ism-server on
// 127.0.0.1 against core run in this process on the same points.
#include <limits>
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/common/gravity_frame.h"
#include "core/common/upright_box.h"
#include "core/io/cloud_io.h"
#include "core/model/model_file.h"
#include "core/recognition/recognizer.h"
#include "proto/wire/messages.h"
#include "tests/service/service_fixture.h"

namespace ism::testing {
namespace {

using v1::FurnitureRecognizer;

class AnswersTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { server_ = new ServerProcess(); }
  static void TearDownTestSuite() {
    delete server_;
    server_ = nullptr;
  }

  static grpc::Status recognize(const v1::Scene& scene, const v1::RecognitionOptions& options,
                                v1::RecognizeResponse* response) {
    v1::RecognizeRequest request;
    *request.mutable_scene() = scene;
    *request.mutable_options() = options;
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
    return FurnitureRecognizer::NewStub(server_->channel())->Recognize(&context, request, response);
  }

  // The small scene's points as the server decodes them, with the up the request gives.
  static Scene localScene(const SyntheticScene& scene, const v1::Scene& message) {
    const std::string& xyz = message.cloud().xyz();
    Scene local = sceneFromPacked(reinterpret_cast<const float*>(xyz.data()), xyz.size() / 12, nullptr,
                                  static_cast<int>(message.cloud().width()), static_cast<int>(message.cloud().height()));
    local.sensor_origin = scene.scene.sensor_origin;
    local.up = wire::upFromProto(message);
    return local;
  }

  static const Model& model() {
    static const Model loaded = loadModel(tinyModelDirectory() + "/default.ismm");
    return loaded;
  }

  static ServerProcess* server_;
};
ServerProcess* AnswersTest::server_ = nullptr;

// The tiny test model finds its objects with some confidence from 320x240 on (at 160x120 its
// calibration gives every peak less than 1%).
SyntheticScene confidentScene() { return smallScene(0, 320, 240); }

// The small scene is a world-frame cloud (z up) sent without a sensor orientation: only a given
// up tells the server where its floor is. It goes as its whole pixel grid (NaN where the render
// has no point), as a sensor's organized cloud would: the same keypoints as the training's scans.
v1::Scene zUpCloud(const SyntheticScene& scene) {
  const Scene& points = scene.scene;
  v1::Scene message;
  const size_t pixels = static_cast<size_t>(points.image_width) * static_cast<size_t>(points.image_height);
  std::vector<float> grid(pixels * 3, std::numeric_limits<float>::quiet_NaN());
  for (size_t i = 0; i < points.cloud->size(); ++i) {
    const auto& p = (*points.cloud)[i];
    const size_t pixel = static_cast<size_t>(points.pixel_index[i]);
    grid[pixel * 3] = p.x, grid[pixel * 3 + 1] = p.y, grid[pixel * 3 + 2] = p.z;
  }
  message.mutable_cloud()->set_xyz(std::string(reinterpret_cast<const char*>(grid.data()), grid.size() * sizeof(float)));
  message.mutable_cloud()->set_width(static_cast<uint32_t>(points.image_width));
  message.mutable_cloud()->set_height(static_cast<uint32_t>(points.image_height));
  wire::toProto(points.sensor_origin, message.mutable_sensor_origin());
  wire::toProto(Eigen::Vector3f::UnitZ(), message.mutable_up());
  return message;
}

void expectSameHypotheses(const v1::RecognitionResult& got, const RecognitionResult& want) {
  ASSERT_EQ(got.hypotheses_size(), static_cast<int>(want.hypotheses.size()));
  for (int i = 0; i < got.hypotheses_size(); ++i) {
    SCOPED_TRACE("hypothesis " + std::to_string(i));
    const auto& g = got.hypotheses(i);
    const Hypothesis& w = want.hypotheses[static_cast<size_t>(i)];
    EXPECT_EQ(g.category(), w.category);
    EXPECT_NEAR(g.score(), w.score, 1e-4 * std::max(1.0f, w.score));
    EXPECT_FLOAT_EQ(g.threshold(), w.threshold);
    EXPECT_NEAR(g.confidence(), w.confidence, 1e-5);
    EXPECT_EQ(g.upright_box(), w.upright_box);
    EXPECT_EQ(g.passed_selection(), w.passed_selection);
    ASSERT_EQ(g.alternatives_size(), static_cast<int>(w.alternatives.size()));
    for (int a = 0; a < g.alternatives_size(); ++a) {
      EXPECT_EQ(g.alternatives(a).category(), w.alternatives[static_cast<size_t>(a)].category);
      EXPECT_NEAR(g.alternatives(a).confidence(), w.alternatives[static_cast<size_t>(a)].confidence, 1e-5);
    }
  }
}

// The default preset: confidences in [0, 1], best first, and no two answers on one object (by the
// test suppression.h applies: overlapping upright boxes, or, within a category, a centre in the
// other's footprint).
TEST_F(AnswersTest, DefaultPresetAnswersEachObjectOnceWithAConfidence) {
  const SyntheticScene scene = confidentScene();
  const v1::Scene message = zUpCloud(scene);
  v1::RecognitionOptions options;
  options.set_min_confidence(0.01f);  // as many peaks as recognition looks at, to have some to merge
  v1::RecognizeResponse response;
  const grpc::Status status = recognize(message, options, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  const auto& result = response.result();
  ASSERT_GT(result.hypotheses_size(), 0);
  ASSERT_TRUE(result.has_gravity());
  const Eigen::Matrix3f to_gravity = gravityRotation(wire::fromProto(result.gravity().up()));

  std::vector<UprightBox> boxes;
  for (int i = 0; i < result.hypotheses_size(); ++i) {
    const auto& h = result.hypotheses(i);
    EXPECT_GE(h.confidence(), 0.01f) << i;
    EXPECT_LE(h.confidence(), 1.0f) << i;
    if (i > 0) EXPECT_LE(h.confidence(), result.hypotheses(i - 1).confidence()) << "not best first at " << i;
    EXPECT_TRUE(h.upright_box()) << i;  // the tiny model's votes are upright, so are its boxes
    // The test model keeps training shapes, so every hypothesis is verified against the scene.
    ASSERT_TRUE(h.has_verification()) << i;
    EXPECT_GT(h.verification().seen(), 0u) << i;
    EXPECT_GT(h.verification().fit(), 0.0f) << i;
    EXPECT_LT(h.verification().fit(), 1.0f) << i;
    for (const auto& a : h.alternatives()) {
      EXPECT_NE(a.category(), h.category());
      EXPECT_LE(a.confidence(), h.confidence());
    }
    OrientedBox box;
    box.center = wire::fromProto(h.box().center());
    box.size = wire::fromProto(h.box().size());
    box.rotation = wire::fromProto(h.box().rotation());
    boxes.push_back(uprightBoxOf(box, to_gravity));
  }
  const auto inside = [](const UprightBox& outer, const Eigen::Vector3f& p) {
    const Eigen::Vector2f local = Eigen::Rotation2Df(-outer.yaw) * (p.head<2>() - outer.center.head<2>());
    return std::abs(local.x()) <= outer.size.x() / 2 && std::abs(local.y()) <= outer.size.y() / 2;
  };
  for (size_t i = 0; i < boxes.size(); ++i) {
    for (size_t j = i + 1; j < boxes.size(); ++j) {
      EXPECT_LT(intersectionOverUnion(boxes[i], boxes[j]), 0.25f) << i << " and " << j;
      if (result.hypotheses(static_cast<int>(i)).category() != result.hypotheses(static_cast<int>(j)).category()) continue;
      EXPECT_FALSE(inside(boxes[i], boxes[j].center) || inside(boxes[j], boxes[i].center)) << i << " and " << j;
    }
  }

  // Exactly core's answer for the same points and up, which the server must not change.
  RecognitionOptions core_options;
  core_options.strategy.activation = model().trained_knn;
  core_options.min_confidence = 0.01f;
  expectSameHypotheses(result, ism::recognize(model(), localScene(scene, message), core_options));

  // Without one answer per object the same peaks come back unmerged: the scene has some to merge,
  // so the check above had something to find.
  options.set_one_answer_per_object(false);
  v1::RecognizeResponse every_peak;
  ASSERT_TRUE(recognize(message, options, &every_peak).ok());
  EXPECT_GT(every_peak.result().hypotheses_size(), result.hypotheses_size());
}

// min_confidence filters on the same confidences: a higher one keeps a prefix of the answers.
TEST_F(AnswersTest, MinConfidenceDropsTheLessConfident) {
  const v1::Scene message = zUpCloud(confidentScene());
  v1::RecognitionOptions options;
  options.set_min_confidence(0.01f);
  v1::RecognizeResponse all;
  ASSERT_TRUE(recognize(message, options, &all).ok());
  ASSERT_GT(all.result().hypotheses_size(), 1);
  // Between the two most confident answers' confidences: the first stays, the second goes.
  const float cut = (all.result().hypotheses(0).confidence() + all.result().hypotheses(1).confidence()) / 2;
  ASSERT_GT(all.result().hypotheses(0).confidence(), all.result().hypotheses(1).confidence());
  options.set_min_confidence(cut);
  v1::RecognizeResponse confident;
  ASSERT_TRUE(recognize(message, options, &confident).ok());
  ASSERT_GE(confident.result().hypotheses_size(), 1);
  for (const auto& h : confident.result().hypotheses()) EXPECT_GE(h.confidence(), cut);
  EXPECT_EQ(confident.result().hypotheses(0).category(), all.result().hypotheses(0).category());
}

// The seed preset answers as the seed's pipeline did: every peak above the leave-one-out
// threshold, ranked by score / threshold, the box selection applied, nothing merged.
TEST_F(AnswersTest, SeedPresetAnswersAsTheSeedDid) {
  const SyntheticScene scene = smallScene();
  const v1::Scene message = zUpCloud(scene);
  v1::RecognitionOptions options;
  options.set_preset(v1::RECOGNITION_PRESET_SEED);
  options.set_min_score(0.0f);  // every Hough maximum, so that there is plenty to compare
  options.set_box_selection(false);
  options.set_max_hypotheses(8);
  v1::RecognizeResponse response;
  const grpc::Status status = recognize(message, options, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  const auto& result = response.result();
  ASSERT_GT(result.hypotheses_size(), 1);
  for (int i = 1; i < result.hypotheses_size(); ++i) {
    const auto& a = result.hypotheses(i - 1);
    const auto& b = result.hypotheses(i);
    EXPECT_GE(a.score() / a.threshold(), b.score() / b.threshold()) << "not ranked by score / threshold at " << i;
  }
  // Nothing merged into alternatives, and the seed's boxes: the supporting keypoints' PCA boxes.
  for (const auto& h : result.hypotheses()) {
    EXPECT_EQ(h.alternatives_size(), 0);
    EXPECT_FALSE(h.upright_box());
  }

  RecognitionOptions core_options;
  core_options.preset = RecognitionPreset::kSeed;
  core_options.strategy.activation = model().trained_knn;
  core_options.min_score = 0.0f;
  core_options.box_selection = false;
  core_options.max_hypotheses = 8;
  expectSameHypotheses(result, ism::recognize(model(), localScene(scene, message), core_options));

}

// A given up is used as given (normalised) and reported back as such; the floor is then found
// along it.
TEST_F(AnswersTest, AGivenUpIsReportedBack) {
  const SyntheticScene scene = smallScene();
  v1::Scene message = cloudMessage(scene.scene);
  const Eigen::Vector3f up(0.0f, 0.1f, 2.0f);  // any length; a little tilted, so it is not a default
  wire::toProto(up, message.mutable_up());
  v1::RecognizeResponse response;
  const grpc::Status status = recognize(message, {}, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_TRUE(response.result().has_gravity());
  const auto& gravity = response.result().gravity();
  EXPECT_EQ(gravity.source(), v1::UP_SOURCE_GIVEN);
  EXPECT_LT((wire::fromProto(gravity.up()) - up.normalized()).norm(), 1e-5f);
  EXPECT_TRUE(gravity.has_floor_level());
  EXPECT_GT(gravity.floor_points(), 0u);

  // Without it the up is the server's own, never reported as given.
  message.clear_up();
  ASSERT_TRUE(recognize(message, {}, &response).ok());
  ASSERT_TRUE(response.result().has_gravity());
  EXPECT_NE(response.result().gravity().source(), v1::UP_SOURCE_GIVEN);
}

// Bad values of the new fields, in a call and in a stream, are the caller's mistake and say which
// field; the stream goes on past them.
TEST_F(AnswersTest, BadUpAndMinConfidenceAreInvalidArguments) {
  const v1::Scene good = cloudMessage(smallScene().scene);
  struct Case {
    const char* name;
    std::function<void(v1::RecognizeRequest*)> spoil;
    const char* message;
  };
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const std::vector<Case> cases{
      {"zero up", [](auto* r) { r->mutable_scene()->mutable_up(); }, "scene.up = (0, 0, 0) is not a direction"},
      {"NaN up", [&](auto* r) { r->mutable_scene()->mutable_up()->set_z(nan); }, "scene.up = (0, 0, nan)"},
      {"infinite up", [&](auto* r) { r->mutable_scene()->mutable_up()->set_x(inf); }, "scene.up = (inf, 0, 0)"},
      {"negative min_confidence", [](auto* r) { r->mutable_options()->set_min_confidence(-0.1f); },
       "options.min_confidence = -0.1 is not in [0, 0.99]"},
      {"min_confidence 1", [](auto* r) { r->mutable_options()->set_min_confidence(1.0f); },
       "options.min_confidence = 1 is not in [0, 0.99]"},
      {"NaN min_confidence", [&](auto* r) { r->mutable_options()->set_min_confidence(nan); },
       "options.min_confidence = nan"},
      {"unknown preset", [](auto* r) { r->mutable_options()->set_preset(static_cast<v1::RecognitionPreset>(9)); },
       "options.preset 9 is not supported"},
  };
  for (const auto& c : cases) {
    v1::RecognizeRequest request;
    *request.mutable_scene() = good;
    c.spoil(&request);
    v1::RecognizeResponse response;
    const grpc::Status status = recognize(request.scene(), request.options(), &response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << c.name << ": " << status.error_message();
    EXPECT_NE(status.error_message().find(c.message), std::string::npos)
        << c.name << ": '" << status.error_message() << "' lacks '" << c.message << "'";
  }

  // In a stream: the frame with a zero up fails alone, its neighbours are answered.
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
  auto stream = FurnitureRecognizer::NewStub(server_->channel())->StreamFrames(&context);
  for (uint64_t id = 1; id <= 3; ++id) {
    v1::StreamFramesRequest request;
    if (id == 1) request.mutable_settings()->set_policy(v1::BACKPRESSURE_POLICY_EVERY_FRAME);
    request.set_frame_id(id);
    *request.mutable_scene() = good;
    if (id == 2) request.mutable_scene()->mutable_up();
    ASSERT_TRUE(stream->Write(request));
  }
  stream->WritesDone();
  std::vector<v1::FrameResult> results;
  for (v1::FrameResult result; stream->Read(&result);) results.push_back(result);
  const grpc::Status status = stream->Finish();
  EXPECT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(results.size(), 3u);
  EXPECT_TRUE(results[0].has_result());
  ASSERT_TRUE(results[1].has_error());
  EXPECT_EQ(results[1].error().code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(results[1].error().message().find("scene.up"), std::string::npos) << results[1].error().message();
  EXPECT_TRUE(results[2].has_result());
}

}  // namespace
}  // namespace ism::testing
