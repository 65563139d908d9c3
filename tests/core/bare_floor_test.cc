// Bare floor: a couch on legs covers the floor under it; a row of chairs and empty floor do not.
#include "core/recognition/bare_floor.h"

#include <cmath>
#include <vector>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "core/common/upright_box.h"
#include "tests/common/map_surfaces.h"
#include "tests/common/verified_hypothesis.h"

namespace ism {
namespace {

using testing::plate;
using testing::verifiedCouchAt;

// As a map, the floor measured everywhere (under furniture on legs too): a couch on legs 2 x 0.9 m
// at y = -2 m (its seat at 0.45 m), three chairs in a row at y = 2 m (seats 0.4 m square, 0.3 m
// apart), and nothing at y = 0.
VerificationScene scene() {
  VerificationScene view;
  view.floor_z = 0.0f;
  view.map = true;
  plate(view.points, -3.0f, 3.0f, -3.5f, 3.5f, 0.0f);
  plate(view.points, -1.0f, 1.0f, -2.45f, -1.55f, 0.45f);
  for (const float x : {-0.7f, 0.0f, 0.7f}) plate(view.points, x - 0.2f, x + 0.2f, 1.8f, 2.2f, 0.45f);
  return view;
}

TEST(BareFloor, ACouchOnLegsCoversTheFloorUnderIt) {
  const VerificationScene view = scene();
  const BareFloorCheck couch = checkBareFloor(view, verifiedCouchAt(-2.0f), true);
  EXPECT_TRUE(couch.looked);
  EXPECT_EQ(couch.bare, 0.0f) << "the floor under the seat is covered";
  EXPECT_FALSE(couch.bareFloor());

  const BareFloorCheck chairs = checkBareFloor(view, verifiedCouchAt(2.0f), true);
  EXPECT_GT(chairs.bare, 0.3f) << "the floor between the chairs, with nothing over it";
  EXPECT_LT(chairs.bare, 0.8f);
  EXPECT_TRUE(chairs.bareFloor());

  const BareFloorCheck empty = checkBareFloor(view, verifiedCouchAt(0.0f), true);
  EXPECT_EQ(empty.bare, 1.0f);
  EXPECT_TRUE(empty.bareFloor());

  // In one frame a seat may hide behind its backrest while the floor shows under it: maps only.
  VerificationScene frame = scene();
  frame.map = false;
  EXPECT_FALSE(checkBareFloor(frame, verifiedCouchAt(0.0f), true).looked);
  BareFloorParams every_scene;
  every_scene.maps_only = false;
  EXPECT_TRUE(checkBareFloor(frame, verifiedCouchAt(0.0f), true, every_scene).bareFloor());

  // Not looked at: a category whose shapes leave their footprint open, unverified, or switched off.
  EXPECT_FALSE(checkBareFloor(view, verifiedCouchAt(0.0f), false).looked);
  Hypothesis unverified = verifiedCouchAt(0.0f);
  unverified.verification.reset();
  EXPECT_FALSE(checkBareFloor(view, unverified, true).looked);
  BareFloorParams off;
  off.enabled = false;
  EXPECT_FALSE(checkBareFloor(view, verifiedCouchAt(0.0f), true, off).bareFloor());
}

TEST(BareFloor, TheShareCountsFloorWithNothingOverIt) {
  std::vector<Eigen::Vector3f> points;  // a 1 m square's inner 0.6 m: floor all over, a top over half
  plate(points, -0.5f, 0.5f, -0.5f, 0.5f, 0.0f);
  plate(points, -0.5f, -0.01f, -0.5f, 0.5f, 0.7f);
  EXPECT_NEAR(bareShare(points, 1.0f, 1.0f, 0.75f), 0.5f, 0.1f);
  // Surface far over the top covers nothing: a shelf over empty floor.
  plate(points, 0.01f, 0.5f, -0.5f, 0.5f, 1.5f);
  EXPECT_NEAR(bareShare(points, 1.0f, 1.0f, 0.75f), 0.5f, 0.1f);
  // Without measured floor nothing is bare: a frame's floor hidden behind the object.
  std::vector<Eigen::Vector3f> no_floor;
  plate(no_floor, -0.5f, -0.01f, -0.5f, 0.5f, 0.7f);
  EXPECT_EQ(bareShare(no_floor, 1.0f, 1.0f, 0.75f), 0.0f);
}

// Only for categories each of whose training shapes covers the middle of its footprint.
TEST(BareFloor, OnlyForCategoriesWhoseShapesCoverTheirFootprint) {
  TrainingObject couch, stand;
  couch.size = {2.0f, 0.9f, 0.85f};
  plate(couch.surface, -1.0f, 1.0f, -0.45f, 0.45f, 0.45f);
  stand.size = {0.6f, 0.6f, 1.8f};  // a coat stand: a pole on a cross of feet
  for (float z = 0.0f; z < 1.8f; z += 0.05f) stand.surface.emplace_back(0.0f, 0.0f, z);
  for (float t = -0.3f; t <= 0.3f; t += 0.05f) {
    stand.surface.emplace_back(t, 0.0f, 0.02f);
    stand.surface.emplace_back(0.0f, t, 0.02f);
  }
  CategoryModel couches, stands, mixed, shapeless;
  couches.objects = {couch, couch};
  stands.objects = {stand};
  mixed.objects = {couch, stand};
  shapeless.objects.resize(2);
  EXPECT_TRUE(footprintCoveredTrained(couches));
  EXPECT_FALSE(footprintCoveredTrained(stands));
  EXPECT_FALSE(footprintCoveredTrained(mixed)) << "one shape leaves its footprint open";
  EXPECT_FALSE(footprintCoveredTrained(shapeless));
  BareFloorParams off;
  off.enabled = false;
  EXPECT_FALSE(footprintCoveredTrained(couches, off));
}

}  // namespace
}  // namespace ism
