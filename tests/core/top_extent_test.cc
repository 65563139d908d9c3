// A table's box from the scene's table top: a long desk rendered with a chair pushed to it, and
// a hypothesis whose fitted shape covers only one end of it.
#include "core/recognition/top_extent.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "core/common/upright_box.h"
#include "core/model/model_file.h"
#include "core/scanner/scanner.h"
#include "tests/common/known_gravity.h"
#include "tests/common/synthetic_furniture.h"
#include "tests/common/verified_hypothesis.h"

namespace ism {
namespace {

using testing::boxMesh;
using testing::knownFloor;
using testing::merge;

constexpr float kTop = 0.75f;

// A desk 2.4 m x 0.8 m on four legs, centred on the origin along x.
Mesh desk() {
  Mesh m = boxMesh({-1.2f, -0.4f, kTop - 0.03f}, {1.2f, 0.4f, kTop});
  for (const float x : {-1.15f, 1.1f}) {
    for (const float y : {-0.35f, 0.3f}) m = merge(m, boxMesh({x, y, 0}, {x + 0.05f, y + 0.05f, kTop - 0.03f}));
  }
  return m;
}

// The desk, a chair pushed to its far side with its backrest rising past the top's height, and a
// low cabinet standing 0.3 m off its right end, seen from 3 m at a person's height.
SyntheticScene office() {
  const Mesh chair = testing::syntheticFurniture("dining_chair", 0);
  std::vector<SceneObject> objects{{"dining_table", desk(), 0, 0, 0},
                                   {"dining_chair", chair, 0.2f, 0.55f, 0},
                                   {"", boxMesh({-0.3f, -0.3f, 0}, {0.3f, 0.3f, kTop}), 1.8f, 0, 0}};
  SyntheticSceneParams params;
  params.camera_eye = {0.3f, -3.0f, 1.6f};
  params.camera_target = {0.0f, 0.0f, 0.5f};
  params.floor_size = 8.0f;
  return composeScene(objects, params);
}

// A verified hypothesis whose fitted table shape, 1.2 m x 0.8 m, stands on the desk's left end.
Hypothesis leftEnd() {
  UprightBox box;
  box.size = {1.2f, 0.8f, 0.74f};
  box.center = {-0.55f, 0.02f, box.size.z() / 2};
  box.yaw = 0.05f;
  return testing::verifiedHypothesis("dining_table", box);
}

TEST(TopExtent, TheBoxSpansTheWholeTopAndNothingBesideIt) {
  const SyntheticScene rendered = office();
  for (const bool sparse : {false, true}) {
    Scene scene = rendered.scene;
    if (sparse) {  // a room sample without its image grid, a tenth of the points
      Scene sample = scene;
      sample.cloud.reset(new Cloud);
      std::mt19937 rng(3);
      std::bernoulli_distribution keep(0.1);
      for (const auto& p : scene.cloud->points) {
        if (keep(rng)) sample.cloud->push_back(p);
      }
      sample.image_width = sample.image_height = 0;
      scene = sample;
    }
    Hypothesis h = leftEnd();
    EXPECT_EQ(extendToTop(makeVerificationScene(scene, knownFloor()), h), TopFound::kFound) << "sparse " << sparse;
    const UprightBox box = uprightBoxOf(h.box, Eigen::Matrix3f::Identity());
    // The 2.4 m top within a cell of the grid on each side; neither the chair behind it nor the
    // cabinet of the same height 0.3 m off its end joins it.
    EXPECT_NEAR(box.size.x(), 2.4f, 0.12f) << "sparse " << sparse;
    EXPECT_NEAR(box.size.y(), 0.8f, 0.12f) << "sparse " << sparse;
    EXPECT_NEAR(box.center.x(), 0.0f, 0.06f) << "sparse " << sparse;
    EXPECT_NEAR(box.center.y(), 0.0f, 0.06f) << "sparse " << sparse;
    EXPECT_NEAR(box.size.z(), kTop, 0.03f) << "from the floor to the top, sparse " << sparse;
    EXPECT_NEAR(box.center.z(), kTop / 2, 0.02f);
    EXPECT_NEAR(std::abs(std::remainder(box.yaw, static_cast<float>(M_PI))), 0.0f, 0.06f);
  }
}

// A desk's top alone, measured every centimetre: nothing else stands at its height, so its edges
// are the edges of all the layer holds, where the grid's morphology stops looking. The box keeps
// them: the top's 2.4 m x 0.8 m and half a sample's spacing on each side.
TEST(TopExtent, ATopAloneAtItsHeightKeepsItsEdges) {
  VerificationScene scene;
  scene.floor_z = 0.0f;
  for (int i = 0; i <= 240; ++i) {
    for (int j = 0; j <= 80; ++j) scene.points.emplace_back(-1.2f + 0.01f * i, -0.4f + 0.01f * j, kTop);
  }
  Hypothesis h = leftEnd();
  ASSERT_EQ(extendToTop(scene, h), TopFound::kFound);
  const UprightBox box = uprightBoxOf(h.box, Eigen::Matrix3f::Identity());
  EXPECT_NEAR(box.size.x(), 2.41f, 0.002f);
  EXPECT_NEAR(box.size.y(), 0.81f, 0.002f);
  EXPECT_NEAR(box.center.x(), 0.0f, 0.002f);
  EXPECT_NEAR(box.center.y(), 0.0f, 0.002f);
  EXPECT_NEAR(box.size.z(), kTop, 0.001f);
}

TEST(TopExtent, WithoutATopTheFittedShapeStays) {
  Hypothesis h = leftEnd();
  UprightBox box = uprightBoxOf(h.box, Eigen::Matrix3f::Identity());
  box.center.x() = -2.6f;  // over bare floor, left of the desk
  h.box = box.toScene(Eigen::Matrix3f::Identity());
  const OrientedBox before = h.box;
  EXPECT_EQ(extendToTop(makeVerificationScene(office().scene, knownFloor()), h), TopFound::kMissing)
      << "no top: recognition drops such a table (TopExtentParams::require_top)";
  EXPECT_TRUE(h.box.center.isApprox(before.center));
  EXPECT_TRUE(h.box.size.isApprox(before.size));
  // Nor is an unverified hypothesis touched, or any when it is turned off.
  Hypothesis unverified = leftEnd();
  unverified.verification.reset();
  const OrientedBox fitted = unverified.box;
  EXPECT_EQ(extendToTop(makeVerificationScene(office().scene, knownFloor()), unverified), TopFound::kNotLooked);
  EXPECT_TRUE(unverified.box.size.isApprox(fitted.size));
  Hypothesis off = leftEnd();
  TopExtentParams params;
  params.enabled = false;
  EXPECT_EQ(extendToTop(makeVerificationScene(office().scene, knownFloor()), off, params), TopFound::kNotLooked);
  EXPECT_TRUE(off.box.size.isApprox(fitted.size));
}

// The desk seen from a seated person's eye height past a chair drawn up to its near side: the
// chair's back hides a swath of the top from the sensor, so the top is measured in two pieces.
// The box spans both, across the hidden swath; with the run across hidden cells turned off it
// stops at the swath. The cabinet beside the desk's end, whose gap the sensor sees, stays out.
TEST(TopExtent, TheTopContinuesPastTheSwathAChairsBackHides) {
  const Mesh chair = testing::syntheticFurniture("dining_chair", 0);
  std::vector<SceneObject> objects{{"dining_table", desk(), 0, 0, 0},
                                   {"dining_chair", chair, 0.3f, -0.55f, static_cast<float>(M_PI)},
                                   {"", boxMesh({-0.3f, -0.3f, 0}, {0.3f, 0.3f, kTop}), 1.8f, 0, 0}};
  SyntheticSceneParams params;
  params.camera_eye = {0.3f, -3.0f, 1.15f};
  params.camera_target = {0.0f, 0.0f, 0.5f};
  params.floor_size = 8.0f;
  const VerificationScene scene = makeVerificationScene(composeScene(objects, params).scene, knownFloor());
  const auto extent = [&](float max_hidden_run) {
    Hypothesis h = leftEnd();
    TopExtentParams top;
    top.max_hidden_run = max_hidden_run;
    EXPECT_EQ(extendToTop(scene, h, top), TopFound::kFound);
    return uprightBoxOf(h.box, Eigen::Matrix3f::Identity());
  };
  const UprightBox whole = extent(TopExtentParams{}.max_hidden_run);
  EXPECT_NEAR(whole.size.x(), 2.4f, 0.12f);
  EXPECT_NEAR(whole.size.y(), 0.8f, 0.12f);
  EXPECT_NEAR(whole.center.x(), 0.0f, 0.06f);
  EXPECT_LT(extent(0.0f).size.x(), 1.8f) << "the swath hidden behind the chair's back splits the measured top";
  // A map has no sensor to hide anything from: its top is what it measured.
  VerificationScene map = scene;
  map.map = true;
  Hypothesis h = leftEnd();
  ASSERT_EQ(extendToTop(map, h), TopFound::kFound);
  EXPECT_LT(uprightBoxOf(h.box, Eigen::Matrix3f::Identity()).size.x(), 1.8f);
}

// A table category whose training objects have these sizes (no shapes).
CategoryModel tablesOfSizes(const std::vector<Eigen::Vector3f>& sizes) {
  CategoryModel tables;
  for (const Eigen::Vector3f& size : sizes) {
    TrainingObject object;
    object.size = size;
    tables.objects.push_back(object);
  }
  return tables;
}

TEST(TopExtent, TheFootprintPriorBoundsATopsDepthNotItsLength) {
  const CategoryModel tables = tablesOfSizes({{1.1f, 0.7f, 0.75f}, {1.24f, 1.24f, 0.74f}});
  const auto top = [](float x, float y, float yaw) {
    UprightBox box;
    box.size = {x, y, 0.75f};
    box.center = {0.3f, -0.2f, 0.375f};
    box.yaw = yaw;
    Hypothesis h;
    h.box = box.toScene(Eigen::Matrix3f::Identity());
    return h;
  };
  const Eigen::Matrix3f up = Eigen::Matrix3f::Identity();
  EXPECT_TRUE(withinFootprintPrior(top(1.6f, 0.8f, 0.3f), tables, up, 0.3f));
  EXPECT_TRUE(withinFootprintPrior(top(5.6f, 1.5f, 1.2f), tables, up, 0.3f)) << "a long table";
  EXPECT_TRUE(withinFootprintPrior(top(0.45f, 0.45f, 0.0f), tables, up, 0.3f)) << "0.7 m less the slack";
  EXPECT_FALSE(withinFootprintPrior(top(2.2f, 1.6f, 0.0f), tables, up, 0.3f)) << "a double bed's top";
  EXPECT_FALSE(withinFootprintPrior(top(1.6f, 0.35f, 0.0f), tables, up, 0.3f)) << "a shelf";
  EXPECT_TRUE(withinFootprintPrior(top(1.6f, 0.8f, 0.0f), CategoryModel{}, up, 0.3f)) << "no objects, no prior";

  // Tables scaled to the typical box (meshes without a size) bound nothing: a square table 1.3 m
  // across passes, as does a bed, and beside a table of given size only that table's depth counts.
  CategoryModel guessed = tables;
  for (auto& o : guessed.objects) o.size_guessed = true;
  EXPECT_TRUE(withinFootprintPrior(top(1.3f, 1.3f, 0.0f), guessed, up, 0.3f));
  EXPECT_TRUE(withinFootprintPrior(top(2.2f, 1.6f, 0.0f), guessed, up, 0.3f));
  CategoryModel mixed = tables;
  mixed.objects[1].size_guessed = true;  // the square one: only 0.7 m deep counts
  EXPECT_FALSE(withinFootprintPrior(top(1.6f, 1.2f, 0.0f), mixed, up, 0.3f));
  EXPECT_TRUE(withinFootprintPrior(top(1.6f, 0.9f, 0.0f), mixed, up, 0.3f));
  EXPECT_TRUE(withinFootprintPrior(top(1.6f, 1.2f, 0.0f), tables, up, 0.3f));
}

TEST(TopExtent, TheHeightPriorBoundsATopsHeight) {
  const CategoryModel tables = tablesOfSizes({{1.1f, 0.7f, 0.72f}, {1.24f, 1.24f, 0.78f}});
  // A top measured at `height` above the floor, as extendToTop boxes it.
  const auto top = [](float height) {
    UprightBox box;
    box.size = {1.6f, 0.8f, height};
    box.center = {0.3f, -0.2f, height / 2};
    box.yaw = 0.4f;
    Hypothesis h;
    h.box = box.toScene(Eigen::Matrix3f::Identity());
    return h;
  };
  const Eigen::Matrix3f up = Eigen::Matrix3f::Identity();
  EXPECT_TRUE(withinHeightPrior(top(0.75f), tables, up, 0.1f));
  EXPECT_TRUE(withinHeightPrior(top(0.63f), tables, up, 0.1f)) << "0.72 m less the slack";
  EXPECT_TRUE(withinHeightPrior(top(0.87f), tables, up, 0.1f)) << "0.78 m and the slack";
  EXPECT_FALSE(withinHeightPrior(top(0.58f), tables, up, 0.1f)) << "an armchair's arms, a low table";
  EXPECT_FALSE(withinHeightPrior(top(0.92f), tables, up, 0.1f)) << "a counter";
  EXPECT_TRUE(withinHeightPrior(top(0.58f), CategoryModel{}, up, 0.1f)) << "no objects, no prior";
  CategoryModel guessed = tables;
  for (auto& o : guessed.objects) o.size_guessed = true;
  EXPECT_TRUE(withinHeightPrior(top(0.58f), guessed, up, 0.1f)) << "heights of meshes scaled to the typical box";
}

TEST(TopExtent, TablesAreFlatToppedChairsAndCouchesAreNot) {
  // The shipped model's training shapes, as recognition reads them.
  const Model model = loadModel(std::string(ISM_SOURCE_DIR) + "/models/default/furniture.ismm");
  for (const auto& category : model.categories) {
    EXPECT_EQ(flatTopped(category), category.name == "dining_table") << category.name;
  }
  CategoryModel none;
  EXPECT_FALSE(flatTopped(none)) << "no shapes, nothing to say";
}

}  // namespace
}  // namespace ism
