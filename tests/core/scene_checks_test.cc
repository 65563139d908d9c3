// The scene's checks as one stage: what each category's training shapes allow, and the verdicts
// recognition and the calibration act on, in a map with a couch, a bed, a table and bare floor.
#include "core/recognition/scene_checks.h"

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "core/common/upright_box.h"
#include "tests/common/map_surfaces.h"
#include "tests/common/verified_hypothesis.h"

namespace ism {
namespace {

using testing::plate;
using testing::verifiedCouchAt;
using testing::verifiedHypothesis;
using testing::wall;

// A couch 2 x 0.9 x 0.85 m as a training shape: a seat at 0.45 m over the front, a back to
// 0.85 m, arms to 0.65 m, its sides down to the floor.
TrainingObject couchShape() {
  TrainingObject couch;
  couch.size = {2.0f, 0.9f, 0.85f};
  testing::couchTop(couch.surface, 0.0f);
  wall(couch.surface, -1.0f, 1.0f, -0.45f, 0.0f, 0.45f);
  return couch;
}

// A table 1.2 x 0.8 x 0.75 m as a training shape: its top.
TrainingObject tableShape() {
  TrainingObject table;
  table.size = {1.2f, 0.8f, 0.75f};
  plate(table.surface, -0.6f, 0.6f, -0.4f, 0.4f, 0.75f);
  return table;
}

// A map: the floor; the couch at y = -2 m (front towards -y), a bed 2 x 1.6 m whose mattress is
// level at 0.6 m at y = 2 m, a table 1.2 x 0.8 m at 0.75 m at x = 3 m; bare floor at the middle.
VerificationScene room() {
  VerificationScene view;
  view.floor_z = 0.0f;
  view.map = true;
  plate(view.points, -3.0f, 4.0f, -3.5f, 3.5f, 0.0f);
  testing::couchTop(view.points, -2.0f);
  wall(view.points, -1.0f, 1.0f, -2.45f, 0.0f, 0.45f);      // the seat's front, down to the floor
  plate(view.points, -1.0f, 1.0f, 1.2f, 2.8f, 0.6f);        // the mattress
  wall(view.points, -1.0f, 1.0f, 1.2f, 0.0f, 0.6f);
  plate(view.points, 2.4f, 3.6f, -0.4f, 0.4f, 0.75f);       // the table's top
  return view;
}

CategoryModel category(const std::string& name, const TrainingObject& shape) {
  CategoryModel c;
  c.name = name;
  c.objects = {shape, shape};
  return c;
}

Hypothesis tableAt(float x) { return testing::verifiedStandingAt("dining_table", {1.2f, 0.8f, 0.75f}, x, 0.0f); }

TEST(SceneChecks, ACouchOnItsSeatIsKeptOnABedRefutedOnBareFloorRejected) {
  const VerificationScene view = room();
  const Model model;
  const CategoryModel couches = category("couch", couchShape());
  const SceneChecks checks(model, couches, SceneCheckParams{});
  const Eigen::Matrix3f up = Eigen::Matrix3f::Identity();
  Hypothesis couch = verifiedCouchAt(-2.0f), bed = verifiedCouchAt(2.0f), bare = verifiedCouchAt(0.0f);
  EXPECT_EQ(checks(view, couch, up), SceneVerdict::kKept);
  EXPECT_EQ(checks(view, bed, up), SceneVerdict::kRefuted) << "a mattress is one level";
  EXPECT_EQ(checks(view, bare, up), SceneVerdict::kRejected) << "nothing stands there";
  SceneCheckParams off;
  off.open_top.max_level = 0;
  EXPECT_EQ(SceneChecks(model, couches, off)(view, bed, up), SceneVerdict::kKept);
}

TEST(SceneChecks, ATableIsItsTop) {
  const VerificationScene view = room();
  const Model model;
  const CategoryModel tables = category("dining_table", tableShape());
  const SceneChecks checks(model, tables, SceneCheckParams{});
  const Eigen::Matrix3f up = Eigen::Matrix3f::Identity();
  Hypothesis table = tableAt(3.2f), topless = tableAt(0.0f);
  EXPECT_EQ(checks(view, table, up), SceneVerdict::kKept);
  EXPECT_NEAR(table.box.center.x(), 3.0f, 0.1f) << "the box is the measured top's";
  EXPECT_EQ(checks(view, topless, up), SceneVerdict::kRejected) << "no top there";
  SceneCheckParams keep;
  keep.top_extent.require_top = false;
  keep.bare_floor.enabled = false;
  Hypothesis kept = tableAt(0.0f);
  EXPECT_EQ(SceneChecks(model, tables, keep)(view, kept, up), SceneVerdict::kKept);
}

// A dining chair 0.5 x 0.5 x 0.9 m as a training shape: its seat at 0.45 m down to the floor in
// front, its backrest along +y to 0.9 m.
TrainingObject chairShape() {
  TrainingObject chair;
  chair.size = {0.5f, 0.5f, 0.9f};
  plate(chair.surface, -0.25f, 0.25f, -0.25f, 0.2f, 0.45f);
  wall(chair.surface, -0.25f, 0.25f, -0.25f, 0.0f, 0.45f);
  wall(chair.surface, -0.25f, 0.25f, 0.22f, 0.0f, 0.9f);
  return chair;
}

// A bench at a bed's foot, its seat at 0.5 m, the mattress level at 0.72 m behind it from y = 0.3 m:
// a chair answered on the bench, its back to the bed, is refuted by the strip behind its back. The
// calibration does not look at the run-on strips (max_run_on 0), and keeps it.
TEST(SceneChecks, AChairWithABedsMattressBehindItsBackIsRefuted) {
  VerificationScene view;
  view.floor_z = 0.0f;
  view.map = true;
  plate(view.points, -3.0f, 3.0f, -3.0f, 3.0f, 0.0f);
  plate(view.points, -0.6f, 0.6f, -0.25f, 0.25f, 0.5f);  // the bench
  wall(view.points, -0.6f, 0.6f, -0.25f, 0.0f, 0.5f);
  plate(view.points, -1.0f, 1.0f, 0.3f, 2.3f, 0.72f);    // the mattress
  wall(view.points, -1.0f, 1.0f, 0.3f, 0.0f, 0.72f);
  const Model model;
  const CategoryModel chairs = category("dining_chair", chairShape());
  const Eigen::Matrix3f up = Eigen::Matrix3f::Identity();
  Hypothesis chair = testing::verifiedStandingAt("dining_chair", {0.5f, 0.5f, 0.9f}, 0.0f, 0.1f);
  chair.verification->object = 0;
  Hypothesis calibrated = chair;
  EXPECT_EQ(SceneChecks(model, chairs, SceneCheckParams{})(view, chair, up), SceneVerdict::kRefuted);
  SceneCheckParams calibration;
  calibration.open_top.max_run_on = 0;
  EXPECT_EQ(SceneChecks(model, chairs, calibration)(view, calibrated, up), SceneVerdict::kKept);
}

}  // namespace
}  // namespace ism
