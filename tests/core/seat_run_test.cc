// A seat's run: a couch-shaped block and an armchair-sized one rendered side by side, and a
// couch category whose one training shape is 2.2 m long.
#include "core/recognition/seat_run.h"

#include <gtest/gtest.h>

#include "core/common/upright_box.h"
#include "core/scanner/scanner.h"
#include "tests/common/known_gravity.h"
#include "tests/common/synthetic_furniture.h"
#include "tests/common/verified_hypothesis.h"

namespace ism {
namespace {

using testing::boxMesh;
using testing::knownFloor;
using testing::merge;

// Points every 5 cm along x at one height, from `from` to `to` (m), on y = 0: mid-cell, so that
// each 10 cm cell from -0.9 m holds two.
std::vector<Eigen::Vector3f> row(float from, float to, float z) {
  std::vector<Eigen::Vector3f> points;
  for (float x = from; x <= to + 1e-4f; x += 0.05f) points.emplace_back(x, 0.0f, z);
  return points;
}

TEST(SeatRun, FollowsTheSurfaceThroughTheMiddle) {
  const Eigen::Vector2f middle = Eigen::Vector2f::Zero(), along_x = Eigen::Vector2f::UnitX();
  EXPECT_NEAR(seatRun(row(-0.875f, 0.875f, 0.4f), middle, along_x, 0.4f, 0.0f), 1.8f, 0.1f);
  // A gap of one 10 cm cell is bridged (cushions, a sparse sample); one of three cells ends the run.
  std::vector<Eigen::Vector3f> small_gap = row(-0.875f, 0.225f, 0.4f), large_gap = row(-0.875f, 0.225f, 0.4f);
  for (const auto& p : row(0.425f, 0.875f, 0.4f)) small_gap.push_back(p);
  for (const auto& p : row(0.625f, 0.875f, 0.4f)) large_gap.push_back(p);
  EXPECT_NEAR(seatRun(small_gap, middle, along_x, 0.4f, 0.0f), 1.8f, 0.1f);
  EXPECT_NEAR(seatRun(large_gap, middle, along_x, 0.4f, 0.0f), 1.2f, 0.1f);
  // Only the band of seat heights counts, only within the half width, only through the middle.
  EXPECT_EQ(seatRun(row(-0.875f, 0.875f, 0.1f), middle, along_x, 0.4f, 0.0f), 0.0f) << "below the band";
  EXPECT_EQ(seatRun(row(-0.875f, 0.875f, 0.9f), middle, along_x, 0.4f, 0.0f), 0.0f) << "above the band";
  EXPECT_EQ(seatRun(row(-0.875f, 0.875f, 0.4f), middle, Eigen::Vector2f::UnitY(), 0.4f, 0.0f), 0.1f)
      << "across the row, only the middle cell";
  EXPECT_EQ(seatRun(row(0.525f, 0.875f, 0.4f), middle, along_x, 0.4f, 0.0f), 0.0f) << "nothing under the middle";
  EXPECT_NEAR(seatRun(row(-0.875f, 0.875f, 1.4f), middle, along_x, 0.4f, 1.0f), 1.8f, 0.1f) << "heights from the floor";
}

// A couch: a seat block 0.45 m high with a back 0.8 m high, `length` long, centred on the origin.
Mesh couch(float length) {
  return merge(boxMesh({-length / 2, -0.4f, 0}, {length / 2, 0.4f, 0.45f}),
               boxMesh({-length / 2, 0.25f, 0.45f}, {length / 2, 0.4f, 0.8f}));
}

CategoryModel couchCategory() {
  CategoryModel category;
  category.name = "couch";
  TrainingObject object;
  object.size = {2.2f, 0.8f, 0.8f};
  object.center_height = 0.4f;
  object.surface = testing::boxSurface({-1.1f, -0.4f, 0}, {1.1f, 0.4f, 0.8f});
  category.objects.push_back(object);
  return category;
}

// A verified couch hypothesis with the training shape's box at (x, y).
Hypothesis couchAt(float x, float y) {
  UprightBox box;
  box.size = {2.2f, 0.8f, 0.8f};
  box.center = {x, y, 0.4f};
  return testing::verifiedHypothesis("couch", box);
}

TEST(SeatRun, ACouchNeedsHalfTheShortestTrainingCouchsLength) {
  // A 1.6 m two-seater on the left, a 0.7 m armchair on the right, seen from 3.5 m.
  std::vector<SceneObject> objects{{"couch", couch(1.6f), -1.2f, 0, 0}, {"", couch(0.7f), 1.2f, 0, 0}};
  SyntheticSceneParams params;
  params.camera_eye = {0.0f, -3.5f, 1.4f};
  params.camera_target = {0.0f, 0.0f, 0.4f};
  params.floor_size = 8.0f;
  const VerificationScene scene = makeVerificationScene(composeScene(objects, params).scene, knownFloor());
  const CategoryModel category = couchCategory();
  ASSERT_NEAR(trainingSeatRun(category).value_or(0), 2.2f, 0.15f) << "within a cell";

  const SeatRunCheck two_seater = checkSeatRun(scene, couchAt(-1.2f, 0), trainingSeatRun(category));
  EXPECT_TRUE(two_seater.looked);
  EXPECT_NEAR(two_seater.run, 1.6f, 0.25f) << "within a cell at each end";
  EXPECT_NEAR(two_seater.required, 1.1f, 0.1f) << "half the training couch's 2.2 m";
  EXPECT_FALSE(two_seater.tooShort());

  const SeatRunCheck armchair = checkSeatRun(scene, couchAt(1.2f, 0), trainingSeatRun(category));
  EXPECT_NEAR(armchair.run, 0.7f, 0.25f);
  EXPECT_TRUE(armchair.tooShort()) << "a couch on an armchair";
  EXPECT_TRUE(checkSeatRun(scene, couchAt(0.0f, -1.5f), trainingSeatRun(category)).tooShort()) << "a couch on bare floor";

  // Not looked at: unverified, switched off, or a category without shapes.
  Hypothesis unverified = couchAt(1.2f, 0);
  unverified.verification.reset();
  EXPECT_FALSE(checkSeatRun(scene, unverified, trainingSeatRun(category)).looked);
  SeatRunParams off;
  off.enabled = false;
  EXPECT_FALSE(checkSeatRun(scene, couchAt(1.2f, 0), trainingSeatRun(category), off).tooShort());
  EXPECT_FALSE(checkSeatRun(scene, couchAt(1.2f, 0), trainingSeatRun(CategoryModel{})).looked);
}

}  // namespace
}  // namespace ism
