#include "core/eval/eval.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/common/error.h"
#include "core/model/model_file.h"
#include "tests/common/synthetic_furniture.h"

namespace ism {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test, removed afterwards.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() / (std::string("ism_eval_") + info->test_suite_name() + "_" + info->name());
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

void writeText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

void writeObj(const Mesh& mesh, const std::string& path) {
  std::ofstream out(path);
  for (const auto& v : mesh.vertices) out << "v " << v.x() << " " << v.y() << " " << v.z() << "\n";
  for (const auto& t : mesh.triangles) out << "f " << t.x() + 1 << " " << t.y() + 1 << " " << t.z() + 1 << "\n";
}

// Procedural furniture written as OBJ files, `variants` meshes per category, +z up at real size.
std::vector<TrainingMesh> syntheticMeshes(const TempDir& dir, const std::vector<std::string>& categories,
                                          int variants) {
  std::vector<TrainingMesh> meshes;
  for (const auto& category : categories) {
    for (int v = 0; v < variants; ++v) {
      TrainingMesh mesh;
      mesh.category = category;
      mesh.path = dir.file(category + "_" + std::to_string(v) + ".obj");
      mesh.placement.up = UpAxis::kZ;
      mesh.credit = "procedural (tests/common)";
      writeObj(testing::syntheticFurniture(category, v), mesh.path);
      meshes.push_back(mesh);
    }
  }
  return meshes;
}

// Small enough for a unit test: few views and small codebooks.
TrainingParams tinyTraining() {
  TrainingParams params;
  params.views.views = 6;
  params.global_kmeans.k = 60;
  params.separated_kmeans.k = 30;
  params.threads = 2;
  return params;
}

Hypothesis hypothesis(const std::string& category, float score, const Eigen::Vector3f& at, bool selected = true) {
  Hypothesis h;
  h.category = category;
  h.score = score;
  h.confidence = score / 10;  // what ranks a class's detections
  h.support_centroid = at;
  h.center = at;
  h.passed_selection = selected;
  return h;
}

GroundTruthObject object(const std::string& category, const Eigen::Vector3f& center) {
  return {category, center, Eigen::Vector3f(0.5f, 0.5f, 0.9f), 0.0f};
}

TEST(EvalMatching, TruePositiveOnlyWithinRadius) {
  const std::vector<Eigen::Vector3f> objects{{0, 0, 0}};
  auto labels = matchDetections({{1.0f, {0.19f, 0, 0}, 0.2f}}, objects);
  EXPECT_EQ(labels[0], MatchLabel::kTruePositive);
  labels = matchDetections({{1.0f, {0.21f, 0, 0}, 0.2f}}, objects);
  EXPECT_EQ(labels[0], MatchLabel::kFalsePositive);
}

TEST(EvalMatching, EachObjectMatchedOnceByTheBestScore) {
  // The lower-scoring detection is listed first: the order of matching is by score.
  auto labels = matchDetections({{0.5f, {0.05f, 0, 0}, 0.2f}, {0.9f, {0.1f, 0, 0}, 0.2f}}, {{0, 0, 0}});
  EXPECT_EQ(labels[1], MatchLabel::kTruePositive);
  EXPECT_EQ(labels[0], MatchLabel::kFalsePositive);
  // Between two objects, a detection takes the nearer one and leaves the other for the next.
  labels = matchDetections({{0.9f, {0.9f, 0, 0}, 1.0f}, {0.8f, {0.4f, 0, 0}, 1.0f}}, {{0, 0, 0}, {1, 0, 0}});
  EXPECT_EQ(labels[0], MatchLabel::kTruePositive);
  EXPECT_EQ(labels[1], MatchLabel::kTruePositive);
}

TEST(EvalMatching, FalsePositivesWithinRadiusOfEachOtherCountOnce) {
  auto labels = matchDetections(
      {{0.9f, {5, 0, 0}, 0.2f}, {0.8f, {5.15f, 0, 0}, 0.2f}, {0.7f, {5.3f, 0, 0}, 0.2f}, {0.6f, {7, 0, 0}, 0.2f}},
      {{0, 0, 0}});
  EXPECT_EQ(labels[0], MatchLabel::kFalsePositive);
  EXPECT_EQ(labels[1], MatchLabel::kMergedFalsePositive);
  // 0.3 from the counted FP, 0.15 from the merged one: merging is with counted FPs only.
  EXPECT_EQ(labels[2], MatchLabel::kFalsePositive);
  EXPECT_EQ(labels[3], MatchLabel::kFalsePositive);
}

TEST(EvalMatching, AveragePrecisionKnownAnswers) {
  // Ranked TP, FP, TP of 3 objects: precision envelope 1 at recall 1/3, 2/3 at recall 2/3.
  EXPECT_NEAR(averagePrecision({{0.7f, true}, {0.9f, true}, {0.8f, false}}, 3), (1.0 + 2.0 / 3.0) / 3.0, 1e-9);
  // An FP ranked first, then all objects found: precision 1/2 and 2/3, envelope 2/3 for both.
  EXPECT_NEAR(averagePrecision({{0.9f, false}, {0.8f, true}, {0.7f, true}}, 2), 2.0 / 3.0, 1e-9);
  EXPECT_DOUBLE_EQ(averagePrecision({{0.9f, true}, {0.1f, false}}, 1), 1.0);
  EXPECT_DOUBLE_EQ(averagePrecision({}, 2), 0.0);
  EXPECT_TRUE(std::isnan(averagePrecision({{0.9f, false}}, 0)));
}

TEST(EvalScorer, RateAndApOverScenesWithMergedChairCategories) {
  Model model;
  for (auto [name, max_edge] : {std::pair{"office_chair", 0.8f}, {"dining_chair", 0.8f}, {"dining_table", 1.6f}}) {
    CategoryModel category;
    category.name = name;
    category.box.max_edge = max_edge;  // radius 0.2 for chairs, 0.4 for tables
    model.categories.push_back(category);
  }
  ClassScorer scorer(model, defaultCategoryMapping());
  // Scene 1: two chairs, a desk and a shelf ("other" is not scored).
  auto counts = scorer.addScene(
      {object("chair", {0, 0, 0}), object("chair", {2, 0, 0}), object("desk", {0, 3, 0}), object("other", {9, 9, 9})},
      {hypothesis("office_chair", 5.0f, {0.1f, 0, 0}),     // TP chair 1
       hypothesis("dining_chair", 4.0f, {0.0f, 0.1f, 0}),  // chair 1 already matched: FP
       hypothesis("dining_chair", 3.0f, {2.3f, 0, 0}),     // 0.3 from chair 2 (radius 0.2): FP
       hypothesis("dining_table", 6.0f, {0.3f, 3, 0}),     // TP desk (radius 0.4)
       hypothesis("dining_table", 9.0f, {9, 9, 9}, false)});  // failed box selection: ignored
  EXPECT_EQ(counts, (std::array<int, 3>{2, 2, 1}));
  // Scene 2: one chair found; two table FPs 0.3 apart (within 0.4) count once.
  counts = scorer.addScene({object("chair", {1, 1, 0})},
                           {hypothesis("office_chair", 2.0f, {1, 1.1f, 0}), hypothesis("dining_table", 7.0f, {5, 5, 0}),
                            hypothesis("dining_table", 1.0f, {5.3f, 5, 0})});
  EXPECT_EQ(counts, (std::array<int, 3>{1, 1, 0}));

  const auto scores = scorer.scores();
  ASSERT_EQ(scores.size(), 2u);
  const ClassScore& chair = scores[0];
  EXPECT_EQ(chair.name, "chair");
  EXPECT_EQ(chair.model_categories, (std::vector<std::string>{"office_chair", "dining_chair"}));
  EXPECT_EQ(chair.objects, 3);
  EXPECT_EQ(chair.tp, 2);
  EXPECT_EQ(chair.fp, 2);
  EXPECT_EQ(chair.fn, 1);
  EXPECT_DOUBLE_EQ(chair.rate, 2.0 / 5.0);
  // Ranked 5 TP, 4 FP, 3 FP, 2 TP: precisions 1, 1/2, 1/3, 1/2 -> envelope 1 and 1/2.
  EXPECT_NEAR(chair.ap, (1.0 + 0.5) / 3.0, 1e-9);
  const ClassScore& table = scores[1];
  EXPECT_EQ(table.name, "table|desk");
  EXPECT_EQ(table.objects, 1);
  EXPECT_EQ(table.tp, 1);
  EXPECT_EQ(table.fp, 1);
  EXPECT_EQ(table.fn, 0);
  EXPECT_DOUBLE_EQ(table.rate, 1.0 / 2.0);
  // Ranked 7 FP, 6 TP: precision 1/2 at full recall.
  EXPECT_NEAR(table.ap, 0.5, 1e-9);
}

TEST(EvalMatching, ByIouTheBestOverlapDecidesAndDuplicatesAreFalsePositives) {
  const std::vector<UprightBox> objects{{{0, 0, 0.45f}, {0.5f, 0.5f, 0.9f}, 0}, {{2, 0, 0.45f}, {0.5f, 0.5f, 0.9f}, 0}};
  const auto detection = [](float score, Eigen::Vector3f center, Eigen::Vector3f size) {
    ScoredDetection d;
    d.score = score;
    d.box = {center, size, 0};
    return d;
  };
  const auto is_tp = matchDetectionsByIou(
      {detection(0.5f, {0.05f, 0, 0.45f}, {0.5f, 0.5f, 0.9f}),   // object 0 again, lower score: duplicate
       detection(0.9f, {0.0f, 0, 0.45f}, {0.5f, 0.5f, 0.9f}),    // object 0 exactly
       detection(0.8f, {2.29f, 0, 0.45f}, {0.5f, 0.5f, 0.9f}),   // IoU 0.27 with object 1
       detection(0.7f, {2.0f, 0, 0.45f}, {1.2f, 1.2f, 1.8f})},   // around object 1, IoU 0.08, and taken
      objects, 0.25f);
  EXPECT_EQ(is_tp, (std::vector<bool>{false, true, true, false}));
  // IoU 0.23: a miss.
  EXPECT_EQ(matchDetectionsByIou({detection(1, {2.31f, 0, 0.45f}, {0.5f, 0.5f, 0.9f})}, objects, 0.25f),
            (std::vector<bool>{false}));
}

TEST(EvalScorer, BoxesAreComparedInTheGravityFrameAndModelNamesMatchTheirOwnObjects) {
  Model model;
  for (const char* name : {"office_chair", "couch"}) {
    CategoryModel category;
    category.name = name;
    category.box.max_edge = 0.8f;
    model.categories.push_back(category);
  }
  ClassScorer scorer(model, defaultCategoryMapping());
  // A camera frame: x right, y down, z forward; up is -y.
  const Eigen::Matrix3f to_gravity = gravityRotation({0, -1, 0});
  // Ground truth: a chair and an object named like the model's couch category (synthetic scenes).
  GroundTruthObject chair{"chair", {0, 0.3f, 2}, {0.5f, 0.5f, 0.9f}, 0};
  GroundTruthObject couch{"couch", {2, 0.4f, 3}, {2.0f, 1.0f, 0.3f}, 0};  // a low bench of a couch
  Hypothesis on_chair = hypothesis("office_chair", 3, chair.center);
  on_chair.box = UprightBox{to_gravity * chair.center, chair.size, 0}.toScene(to_gravity);
  Hypothesis on_couch = hypothesis("couch", 2, couch.center);
  // The couch's box as the camera frame sees it: its height runs along -y.
  on_couch.box.center = couch.center;
  on_couch.box.size = {2.0f, 0.3f, 1.0f};  // x, then the camera's y (height), then z (depth)
  scorer.addScene({chair, couch}, {on_chair, on_couch}, to_gravity);
  const auto scores = scorer.scores();
  ASSERT_EQ(scores.size(), 2u);
  EXPECT_EQ(scores[0].tp25, 1);
  EXPECT_DOUBLE_EQ(scores[0].ap25, 1.0);
  EXPECT_EQ(scores[1].name, "sofa");
  EXPECT_EQ(scores[1].objects, 1);
  EXPECT_EQ(scores[1].tp, 1);
  EXPECT_EQ(scores[1].tp25, 1);
  ASSERT_EQ(scores[1].pr25.size(), 1u);
  EXPECT_EQ(scores[1].pr25[0], (std::pair<double, double>{1.0, 1.0}));
  // Per detection its confidence and verdict; per object what came closest.
  EXPECT_EQ(scores[1].ranked25, (std::vector<std::pair<float, bool>>{{0.2f, true}}));
  ASSERT_EQ(scores[0].outcomes.size(), 1u);
  EXPECT_NEAR(scores[0].outcomes[0].best_iou, 1.0f, 1e-5f);
  EXPECT_FLOAT_EQ(scores[0].outcomes[0].best_iou_confidence, 0.3f);
  EXPECT_NEAR(scores[0].outcomes[0].nearest_distance, 0.0f, 1e-5f);
  // Without the gravity frame the camera-frame couch box stands on its side and misses.
  ClassScorer levelled(model, defaultCategoryMapping());
  levelled.addScene({chair, couch}, {on_chair, on_couch});
  EXPECT_EQ(levelled.scores()[1].tp25, 0);
}

// Each detection is kept with what the calibration weighed, for tests/eval/domain_gap.py.
TEST(EvalScorer, EveryDetectionIsKeptWithItsScoreSupportAndFit) {
  Model model;
  CategoryModel chair_category;
  chair_category.name = "dining_chair";
  chair_category.box.max_edge = 0.9f;
  model.categories.push_back(chair_category);
  ClassScorer scorer(model, defaultCategoryMapping());
  const GroundTruthObject chair{"chair", {0, 0, 0.45f}, {0.5f, 0.5f, 0.9f}, 0};
  Hypothesis on_chair = hypothesis("dining_chair", 4, chair.center);
  on_chair.box = UprightBox{chair.center, chair.size, 0}.toScene(Eigen::Matrix3f::Identity());
  on_chair.support = 35;
  on_chair.verification = Verification{};
  on_chair.verification->seen = 80;
  on_chair.verification->consistent = 60;
  on_chair.verification->profile_distance = 0.4f;
  Hypothesis elsewhere = hypothesis("dining_chair", 2, {3, 0, 0.45f});
  elsewhere.support = 12;
  Hypothesis rejected = hypothesis("dining_chair", 5, {6, 0, 0.45f}, false);  // failed selection: not a detection
  scorer.addScene({chair}, {on_chair, elsewhere, rejected}, Eigen::Matrix3f::Identity(), 0.5f, "room");
  const auto scores = scorer.scores();
  ASSERT_EQ(scores.size(), 1u);
  const auto& candidates = scores[0].candidates;
  ASSERT_EQ(candidates.size(), 2u);
  EXPECT_EQ(candidates[0].scene, "room");
  EXPECT_EQ(candidates[0].category, "dining_chair");
  EXPECT_TRUE(candidates[0].tp25);
  EXPECT_FLOAT_EQ(candidates[0].confidence, 0.4f);
  EXPECT_FLOAT_EQ(candidates[0].score, 4.0f);
  EXPECT_EQ(candidates[0].support, 35);
  EXPECT_TRUE(candidates[0].verified);
  EXPECT_FLOAT_EQ(candidates[0].fit, 0.7f);  // (60 + 10) / (80 + 20)
  EXPECT_FLOAT_EQ(candidates[0].profile_distance, 0.4f);
  EXPECT_FALSE(candidates[1].tp25);
  EXPECT_EQ(candidates[1].support, 12);
  EXPECT_FALSE(candidates[1].verified);
}

TEST(EvalMapping, SpecReplacesOneEntryAndRejectsMalformedText) {
  CategoryMapping mapping = defaultCategoryMapping();
  addCategoryMapping(mapping, "couch=sofa|couch");
  addCategoryMapping(mapping, "bed=bed");
  EXPECT_EQ(mapping.at("couch"), (std::vector<std::string>{"sofa", "couch"}));
  EXPECT_EQ(mapping.at("bed"), (std::vector<std::string>{"bed"}));
  EXPECT_EQ(mapping.at("dining_table"), (std::vector<std::string>{"table", "desk"}));
  for (const char* bad : {"couch", "=sofa", "couch=", "couch=sofa||x"}) {
    EXPECT_THROW(addCategoryMapping(mapping, bad), Error) << bad;
  }
}

TEST(EvalGroundTruth, ParsesDatasetJsonAndFindsScenes) {
  TempDir dir;
  writeText(dir.file("room.pcd"), "");
  writeText(dir.file("room.json"), R"({"scene": "room", "cloud": "room.pcd", "frame": "camera optical frame",
      "objects": [{"category": "chair", "subtype_by_eye": "office_chair", "center": [-0.6, 0.4, 1.9],
                   "size": [0.6, 0.56, 0.94], "yaw": 0.5, "points": 100},
                  {"category": "desk", "center": [0, 0.2, 2.5]}]})");
  const AnnotatedScene scene = readSceneAnnotation(dir.file("room.json"));
  EXPECT_EQ(scene.name, "room");
  EXPECT_EQ(scene.cloud_path, dir.file("room.pcd"));
  ASSERT_EQ(scene.objects.size(), 2u);
  EXPECT_EQ(scene.objects[0].category, "chair");
  EXPECT_TRUE(scene.objects[0].center.isApprox(Eigen::Vector3f(-0.6f, 0.4f, 1.9f)));
  EXPECT_TRUE(scene.objects[0].size.isApprox(Eigen::Vector3f(0.6f, 0.56f, 0.94f)));
  EXPECT_FLOAT_EQ(scene.objects[0].yaw, 0.5f);
  EXPECT_TRUE(scene.objects[1].size.isZero());

  Scene cloud;
  PointT p;
  p.x = 4;
  p.y = 2;
  p.z = 0;
  cloud.cloud->push_back(p);
  EXPECT_TRUE(sceneViewpoint(scene, cloud, ViewpointPolicy::kAuto).isZero());
  EXPECT_TRUE(sceneViewpoint(scene, cloud, ViewpointPolicy::kRoomCentre, 1.5f).isApprox(Eigen::Vector3f(4, 2, 1.5f)));
  // A sensor pose that came with the cloud wins over the frame's wording.
  cloud.sensor_origin = Eigen::Vector3f(0.4f, -2.6f, 1.3f);
  EXPECT_TRUE(sceneViewpoint(scene, cloud, ViewpointPolicy::kAuto).isApprox(cloud.sensor_origin));

  EXPECT_TRUE(scene.to_gravity.isIdentity());
  EXPECT_FALSE(scene.up_is_given);

  // A hand-levelled camera frame: the boxes are along (axes_a, axes_b, floor_normal).
  writeText(dir.file("levelled.json"), R"({"frame": "camera optical frame. up = floor_normal", "cloud": "room.pcd",
      "floor_normal": [0, -0.8, -0.6], "axes_a": [1, 0, 0], "axes_b": [0, -0.6, 0.8], "objects": []})");
  const AnnotatedScene levelled = readSceneAnnotation(dir.file("levelled.json"));
  EXPECT_TRUE((levelled.to_gravity * Eigen::Vector3f(0, -0.8f, -0.6f)).isApprox(Eigen::Vector3f::UnitZ(), 1e-5f));
  EXPECT_TRUE((levelled.to_gravity * Eigen::Vector3f::UnitX()).isApprox(Eigen::Vector3f::UnitX(), 1e-5f));
  EXPECT_FALSE(levelled.up_is_given);
  writeText(dir.file("room_z.json"), R"({"frame": "z up, metres", "cloud": "room.pcd", "objects": []})");
  EXPECT_TRUE(readSceneAnnotation(dir.file("room_z.json")).up_is_given);
  fs::remove(dir.file("levelled.json"));
  fs::remove(dir.file("room_z.json"));

  const std::vector<std::string> expected{dir.file("room.json")};
  EXPECT_EQ(findSceneAnnotations({dir.file("")}), expected);
  EXPECT_EQ(findSceneAnnotations({dir.file("room.pcd")}), expected);
  EXPECT_THROW(findSceneAnnotations({dir.file("absent.pcd")}), Error);
}

TEST(EvalReal, TheGivenUpIsTurnedByTheAskedTiltTowardsItsAzimuth) {
  AnnotatedScene scene;
  scene.to_gravity = gravityRotation(Eigen::Vector3f(0, -0.8f, -0.6f));
  const Eigen::Vector3f up = scene.to_gravity.row(2).transpose();
  RealEvalParams params;
  EXPECT_EQ(givenUp(scene, params), up);  // no tilt: exactly the annotated up
  params.up_tilt_deg = 0.2f;
  for (float azimuth : {0.0f, 90.0f, 225.0f}) {
    params.up_tilt_azimuth_deg = azimuth;
    const Eigen::Vector3f tilted = givenUp(scene, params);
    EXPECT_NEAR(tilted.norm(), 1.0f, 1e-6f);
    EXPECT_NEAR(std::acos(std::min(1.0f, tilted.dot(up))) * 180.0f / static_cast<float>(M_PI), 0.2f, 0.01f);
    // It leans towards the azimuth, measured in the gravity frame from x to y.
    const Eigen::Vector3f lean = scene.to_gravity * (tilted - up);
    const float radians = azimuth * static_cast<float>(M_PI) / 180.0f;
    EXPECT_GT(lean.head<2>().normalized().dot(Eigen::Vector2f(std::cos(radians), std::sin(radians))), 0.999f);
  }
}

TEST(EvalGroundTruth, MalformedFilesNameTheFileAndField) {
  TempDir dir;
  writeText(dir.file("a.pcd"), "");
  auto error_of = [&](const std::string& json) {
    writeText(dir.file("a.json"), json);
    try {
      readSceneAnnotation(dir.file("a.json"));
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(dir.file("a.json")), std::string::npos) << e.what();
      return std::make_pair(e.code(), std::string(e.what()));
    }
    ADD_FAILURE() << "no error for " << json;
    return std::make_pair(ErrorCode::kInternal, std::string());
  };
  auto [code, message] = error_of(R"({"scene": "a", "objects": [)");
  EXPECT_EQ(code, ErrorCode::kInvalidInput);
  EXPECT_NE(message.find("not valid JSON"), std::string::npos) << message;
  std::tie(code, message) = error_of(R"({"scene": "a"})");
  EXPECT_NE(message.find("\"objects\""), std::string::npos) << message;
  std::tie(code, message) = error_of(R"({"objects": [{"category": "chair", "center": [1, 2]}]})");
  EXPECT_NE(message.find("objects[0]"), std::string::npos) << message;
  EXPECT_NE(message.find("\"center\""), std::string::npos) << message;
  std::tie(code, message) = error_of(R"({"objects": [{"center": [1, 2, 3]}]})");
  EXPECT_NE(message.find("\"category\""), std::string::npos) << message;
  std::tie(code, message) = error_of(R"({"cloud": "missing.pcd", "objects": []})");
  EXPECT_EQ(code, ErrorCode::kNotFound);
  EXPECT_NE(message.find("missing.pcd"), std::string::npos) << message;
}

TEST(EvalBaseline, SplitIsDeterministicAndChecksCounts) {
  std::vector<TrainingMesh> meshes;
  for (const char* path : {"c/3.obj", "c/1.obj", "t/2.obj", "c/2.obj", "t/1.obj"}) {
    meshes.push_back({std::string(1, path[0]), path, {}, ""});
  }
  const MeshSplit split = splitMeshes(meshes, 1, 1);
  ASSERT_EQ(split.train.size(), 2u);
  ASSERT_EQ(split.test.size(), 2u);
  EXPECT_EQ(split.train[0].path, "c/1.obj");
  EXPECT_EQ(split.test[0].path, "c/2.obj");
  EXPECT_EQ(split.train[1].path, "t/1.obj");
  EXPECT_EQ(split.test[1].path, "t/2.obj");
  EXPECT_THROW(splitMeshes(meshes, 2, 1), Error);  // category t has only 2 meshes
}

TEST(EvalBaseline, TinySyntheticRunHasSeedTablesAndDominantDiagonal) {
  TempDir dir;
  const std::vector<std::string> categories{"dining_table", "office_chair"};
  const MeshSplit split = splitMeshes(syntheticMeshes(dir, categories, 3), 2, 1);
  const TrainingParams params = tinyTraining();
  const BaselineResult result = runBaseline(split, params);
  const std::string text = formatBaseline(result);
  SCOPED_TRACE(text);  // the tables explain any failure below

  EXPECT_EQ(result.categories, categories);
  EXPECT_EQ(result.training_scans, 2 * 2 * params.views.views);
  EXPECT_EQ(result.test_scans, 2 * params.views.views);
  ASSERT_EQ(result.combinations.size(), 6u);
  std::vector<std::string> with_none = categories;
  with_none.push_back("none");
  for (const auto& c : result.combinations) {
    SCOPED_TRACE(c.strategy);
    EXPECT_EQ(c.generated.rows, categories);
    EXPECT_EQ(c.generated.cols, categories);
    EXPECT_EQ(c.confusion.cols, with_none);
    for (size_t r = 0; r < categories.size(); ++r) {
      int row_total = 0;
      for (int n : c.confusion.counts[r]) row_total += n;
      EXPECT_EQ(row_total, params.views.views);  // every test scan lands in exactly one column
      for (int n : c.generated.counts[r]) EXPECT_LE(n, params.views.views);
    }
  }
  // Summed over the six combinations, a scan's own category must win: hypotheses are generated
  // and selected mostly on the diagonal.
  int generated_diagonal = 0, generated_off = 0, confusion_diagonal = 0, confusion_off = 0;
  for (const auto& c : result.combinations) {
    for (const auto& row : categories) {
      for (const auto& col : categories) {
        (row == col ? generated_diagonal : generated_off) += c.generated.at(row, col);
        (row == col ? confusion_diagonal : confusion_off) += c.confusion.at(row, col);
      }
    }
  }
  EXPECT_GT(generated_diagonal, 2 * generated_off);
  EXPECT_GT(confusion_diagonal, 2 * confusion_off);
  EXPECT_NE(text.find("== global 1nn+lw"), std::string::npos);
  EXPECT_NE(text.find("test \\ model"), std::string::npos);
  EXPECT_NE(baselineToJson(result).find("\"confusion\""), std::string::npos);
}

TEST(EvalReal, KinectScenesAreScoredAgainstTheirGroundTruth) {
  const fs::path kinect = fs::path(ISM_SHARED_DATA_DIR) / "real" / "kinect";
  if (!fs::exists(kinect / "tum_desk.json")) GTEST_SKIP() << "no real scans at " << kinect << " (../shared absent)";
  TempDir dir;
  TrainingParams params = tinyTraining();
  params.separated_codebooks = false;
  const std::vector<std::string> categories{"office_chair", "dining_table"};
  const Model model = trainFromScans(scanMeshes(syntheticMeshes(dir, categories, 2), params), categories, params);

  std::vector<AnnotatedScene> scenes;
  for (const auto& path : findSceneAnnotations({kinect.string()})) scenes.push_back(readSceneAnnotation(path));
  ASSERT_EQ(scenes.size(), 2u);  // office1, tum_desk; chair_from_above.pcd has no ground truth
  RealEvalParams eval;
  eval.strategies = seedCombinations(model);
  ASSERT_EQ(eval.strategies.size(), 3u);  // global codebook only
  const RealResult result = evaluateRealScenes(model, scenes, eval);

  ASSERT_EQ(result.scenes.size(), 2u);
  for (const auto& s : result.scenes) {
    EXPECT_GT(s.points, 100000u) << s.name;  // a 640x480 frame minus pixels without depth
    EXPECT_GT(s.keypoints, 100u) << s.name;
    EXPECT_TRUE(s.viewpoint.isZero()) << s.name;  // camera frames
    EXPECT_EQ(s.recognition_ms.size(), 3u);
  }
  for (const auto& c : result.combinations) {
    ASSERT_EQ(c.classes.size(), 2u);
    EXPECT_EQ(c.classes[0].name, "chair");
    EXPECT_EQ(c.classes[0].objects, 3);  // two in tum_desk, one in office1
    EXPECT_EQ(c.classes[1].name, "table|desk");
    EXPECT_EQ(c.classes[1].objects, 1);
    for (const auto& k : c.classes) {
      EXPECT_EQ(k.tp + k.fn, k.objects);
      EXPECT_NEAR(k.rate, static_cast<double>(k.tp) / (k.objects + k.fp), 1e-12);
    }
  }
  EXPECT_NE(formatReal(result).find("tum_desk"), std::string::npos);
}

// Issue 13's target for the annotated frames, on the shipped model at the default operating point:
// each object of the two Kinect frames and the sample scene (4 chairs, 2 tables or desks, 1 sofa)
// answered by a box of its class at 3D IoU 0.25, and nothing else answered. At min_confidence 0.5
// tum_desk's desk and red chair and office1's chair are missed (docs/EVALUATION.md, "The default
// operating point").
TEST(EvalReal, TheShippedModelAnswersTheAnnotatedFramesObjectByObject) {
  const fs::path kinect = fs::path(ISM_SHARED_DATA_DIR) / "real" / "kinect";
  if (!fs::exists(kinect / "tum_desk.json")) GTEST_SKIP() << "no real scans at " << kinect << " (../shared absent)";
  const fs::path sample = fs::path(ISM_SOURCE_DIR) / "models" / "sample" / "living_room.json";
  std::vector<AnnotatedScene> scenes;
  for (const auto& path : findSceneAnnotations({kinect.string(), sample.string()})) scenes.push_back(readSceneAnnotation(path));
  ASSERT_EQ(scenes.size(), 3u);
  const Model model = loadModel((fs::path(ISM_SOURCE_DIR) / "models" / "default" / "furniture.ismm").string());
  RealEvalParams eval;  // the default preset and operating point
  eval.strategies = {seedCombinations(model).front()};  // global 1nn+lw, as ism-eval real and the service answer
  const RealResult result = evaluateRealScenes(model, scenes, eval);

  ASSERT_EQ(result.combinations.size(), 1u);
  int objects = 0;
  for (const ClassScore& c : result.combinations[0].classes) {
    objects += c.objects;
    EXPECT_EQ(c.tp25, c.objects) << c.name;
    EXPECT_EQ(c.fp25, 0) << c.name;
  }
  EXPECT_EQ(objects, 7);
}

}  // namespace
}  // namespace ism
