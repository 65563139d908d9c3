// A seat's area: a couch shows its seat over its footprint; a desk as long and as deep, on two
// legs and a drawer front, shows a line of parts at seat height and nothing between them. In a
// single view a couch seen from behind hides its seat: hidden is not missing.
#include "core/recognition/seat_area.h"

#include <vector>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "core/common/upright_box.h"
#include "core/scanner/scanner.h"
#include "tests/common/known_gravity.h"
#include "tests/common/map_surfaces.h"
#include "tests/common/synthetic_furniture.h"
#include "tests/common/verified_hypothesis.h"

namespace ism {
namespace {

using testing::couchTop;
using testing::plate;
using testing::wall;

// A map: the floor; a couch 2 x 0.9 m at y = 0; a desk 2 x 0.9 m at y = 2.5 m, its top at 0.75 m,
// a leg at each end and a drawer front along its front edge.
VerificationScene scene() {
  VerificationScene view;
  view.floor_z = 0.0f;
  view.map = true;
  plate(view.points, -3.0f, 3.0f, -2.0f, 4.0f, 0.0f);
  couchTop(view.points, 0.0f);
  wall(view.points, -1.0f, 1.0f, -0.45f, 0.0f, 0.45f);  // its front
  plate(view.points, -1.0f, 1.0f, 2.05f, 2.95f, 0.75f);  // the desk's top
  for (const float x : {-0.95f, 0.95f}) wall(view.points, x - 0.02f, x + 0.02f, 2.5f, 0.0f, 0.72f);
  wall(view.points, 0.4f, 0.95f, 2.1f, 0.3f, 0.72f);  // the drawers' front
  return view;
}

TEST(SeatArea, ACouchShowsItsSeatADeskDoesNot) {
  const VerificationScene view = scene();
  const SeatAreaCheck couch = checkSeatArea(view, testing::verifiedCouchAt(0.0f), true);
  EXPECT_TRUE(couch.looked);
  EXPECT_GT(couch.share, 0.8f) << "the seat and the arms: all but the back's strip, whose top is higher";
  EXPECT_FALSE(couch.bare());
  const SeatAreaCheck desk = checkSeatArea(view, testing::verifiedCouchAt(2.5f), true);
  EXPECT_LT(desk.share, 0.2f) << "the drawers' front is one row of cells, the legs are outside";
  EXPECT_TRUE(desk.bare());
  SeatAreaParams off;
  off.enabled = false;
  EXPECT_FALSE(checkSeatArea(view, testing::verifiedCouchAt(2.5f), true, off).bare());
  EXPECT_FALSE(checkSeatArea(view, testing::verifiedCouchAt(2.5f), false).looked) << "its category shows no seat";
  Hypothesis unverified = testing::verifiedCouchAt(2.5f);
  unverified.verification.reset();
  EXPECT_FALSE(checkSeatArea(view, unverified, true).looked);
}

// A couch 2 x 0.9 m at (x, 0): a seat block 0.45 m high, its back (0.15 m deep, 0.85 m high) on
// its +y side. A desk 2 x 0.9 m: a top 0.72-0.75 m high on four legs.
Mesh couchMesh() {
  return testing::merge(testing::boxMesh({-1.0f, -0.45f, 0}, {1.0f, 0.45f, 0.45f}),
                        testing::boxMesh({-1.0f, 0.3f, 0.45f}, {1.0f, 0.45f, 0.85f}));
}
Mesh deskMesh() {
  Mesh desk = testing::boxMesh({-1.0f, -0.45f, 0.72f}, {1.0f, 0.45f, 0.75f});
  for (const float x : {-0.95f, 0.95f}) {
    for (const float y : {-0.4f, 0.4f}) desk = testing::merge(desk, testing::boxMesh({x - 0.03f, y - 0.03f, 0}, {x + 0.03f, y + 0.03f, 0.72f}));
  }
  return desk;
}

// One rendered view of the couch at x = -1.3 m and the desk at x = 1.3 m from (0, eye_y) at 1.3 m.
VerificationScene singleView(float eye_y) {
  std::vector<SceneObject> objects{{"couch", couchMesh(), -1.3f, 0, 0}, {"", deskMesh(), 1.3f, 0, 0}};
  SyntheticSceneParams params;
  params.camera_eye = {0.0f, eye_y, 1.3f};
  params.camera_target = {0.0f, 0.0f, 0.4f};
  params.floor_size = 8.0f;
  return makeVerificationScene(composeScene(objects, params).scene, testing::knownFloor());
}

Hypothesis couchAt(float x) { return testing::verifiedStandingAt("couch", {2.0f, 0.9f, 0.85f}, x, 0.0f); }

TEST(SeatArea, ASingleViewCountsOnlyTheCellsItSaw) {
  const VerificationScene front = singleView(-3.5f);
  ASSERT_FALSE(front.map);
  const SeatAreaCheck couch = checkSeatArea(front, couchAt(-1.3f), true);
  EXPECT_TRUE(couch.looked);
  EXPECT_FALSE(couch.bare()) << "its seat faces the sensor";
  const SeatAreaCheck desk = checkSeatArea(front, couchAt(1.3f), true);
  EXPECT_TRUE(desk.looked) << "the sensor sees under the top, to the floor behind";
  EXPECT_TRUE(desk.bare());

  const VerificationScene back = singleView(3.5f);
  const SeatAreaCheck behind = checkSeatArea(back, couchAt(-1.3f), true);
  EXPECT_LT(behind.seen, 0.3f) << "its back hides the seat";
  EXPECT_FALSE(behind.bare()) << "hidden, not missing";
  VerificationScene as_map = back;  // what the same points would say if every cell counted
  as_map.map = true;
  EXPECT_TRUE(checkSeatArea(as_map, couchAt(-1.3f), true).bare());
}

TEST(SeatArea, TheShareCountsTheInnerFootprintsCellsAtSeatHeight) {
  std::vector<Eigen::Vector3f> half;  // a seat over one half of a 1 m square
  plate(half, -0.5f, -0.05f, -0.5f, 0.5f, 0.45f);
  EXPECT_NEAR(seatAreaShare(half, 1.0f, 1.0f), 0.5f, 0.1f);
  std::vector<Eigen::Vector3f> off_band;  // the floor's clutter and a table's top are not a seat
  plate(off_band, -0.5f, 0.5f, -0.5f, 0.5f, 0.1f);
  plate(off_band, -0.5f, 0.5f, -0.5f, 0.5f, 0.75f);
  EXPECT_EQ(seatAreaShare(off_band, 1.0f, 1.0f), 0.0f);
  std::vector<Eigen::Vector3f> rim;  // a neighbour's edge, outside the inner footprint
  wall(rim, -0.5f, 0.5f, 0.5f, 0.3f, 0.6f);
  EXPECT_EQ(seatAreaShare(rim, 1.0f, 1.0f), 0.0f);
  EXPECT_EQ(seatAreaShare(half, 0.0f, 1.0f), 0.0f) << "no footprint, no seat";
}

TEST(SeatArea, OnlyCategoriesWhoseShapesAllShowASeatAreLookedAt) {
  CategoryModel seats;
  TrainingObject couch;
  couch.size = {2.0f, 0.9f, 0.85f};
  couchTop(couch.surface, 0.0f);
  seats.objects.push_back(couch);
  EXPECT_TRUE(seatAreaTrained(seats));
  TrainingObject stool;  // a bar stool: its seat at 0.8 m on one post
  stool.size = {0.4f, 0.4f, 0.8f};
  plate(stool.surface, -0.2f, 0.2f, -0.2f, 0.2f, 0.8f);
  wall(stool.surface, -0.02f, 0.02f, 0.0f, 0.0f, 0.8f);
  seats.objects.push_back(stool);
  EXPECT_FALSE(seatAreaTrained(seats));
  seats.objects.back().surface.clear();  // a shape the calibration holds out says nothing
  EXPECT_TRUE(seatAreaTrained(seats));
  EXPECT_FALSE(seatAreaTrained(CategoryModel{})) << "no shapes";
  SeatAreaParams off;
  off.enabled = false;
  EXPECT_FALSE(seatAreaTrained(seats, off));
}

}  // namespace
}  // namespace ism
