// An open top: a chair standing free, the same chair under a wall cabinet, and a coffee table.
#include "core/recognition/open_top.h"

#include <cmath>
#include <limits>
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
using testing::wall;

// A chair 0.5 m square (a seat at 0.45 m, a backrest to 0.9 m) at x = -1 m, the same chair at
// x = 1 m under a wall cabinet whose bottom is 0.3 m over the chair's top, a coffee table's top
// 0.6 m square at 0.45 m at y = 1.5 m, and the floor, as a map: points all round, the floor at z = 0.
VerificationScene scene() {
  VerificationScene view;
  view.floor_z = 0.0f;
  view.map = true;
  plate(view.points, -3.0f, 3.0f, -2.0f, 2.0f, 0.0f);
  for (const float x : {-1.0f, 1.0f}) {
    plate(view.points, x - 0.25f, x + 0.25f, -0.25f, 0.25f, 0.45f);
    wall(view.points, x - 0.25f, x + 0.25f, 0.22f, 0.5f, 0.9f);
  }
  plate(view.points, 0.6f, 1.4f, -0.3f, 0.3f, 1.2f);   // the cabinet's bottom
  wall(view.points, 0.6f, 1.4f, -0.3f, 1.2f, 1.5f);    // its front
  plate(view.points, -0.3f, 0.3f, 1.2f, 1.8f, 0.45f);  // a coffee table's top at y = 1.5 m
  return view;
}

Hypothesis chairAt(float x, float y = 0) {
  UprightBox box;
  box.size = {0.5f, 0.5f, 0.9f};
  box.center = {x, y, 0.45f};
  return testing::verifiedHypothesis("dining_chair", box);
}

TEST(OpenTop, NothingMayStandOverAChair) {
  const VerificationScene view = scene();
  const OpenTopCheck free = checkOpenTop(view, chairAt(-1.0f));
  EXPECT_TRUE(free.looked);
  EXPECT_GT(free.body, 20) << "the seat and the backrest";
  EXPECT_EQ(free.above, 0);
  EXPECT_FALSE(free.covered());
  EXPECT_GT(free.upper, 10) << "the backrest from 0.55 to 0.75 m";
  EXPECT_FALSE(free.topless());
  EXPECT_FALSE(free.contradicted());

  const OpenTopCheck under = checkOpenTop(view, chairAt(1.0f));
  EXPECT_GT(under.above, 50) << "the cabinet's bottom";
  EXPECT_GT(under.share(), 0.2f);
  EXPECT_TRUE(under.covered()) << "a chair inside a shelf or under a cabinet";
  EXPECT_TRUE(under.contradicted());

  // Surface higher than `to` over the top is not looked at: a chair under a high shelf.
  OpenTopParams low;
  low.to = 0.25f;
  EXPECT_FALSE(checkOpenTop(view, chairAt(1.0f), low).covered());

  // Not looked at: unverified, or switched off.
  Hypothesis unverified = chairAt(1.0f);
  unverified.verification.reset();
  EXPECT_FALSE(checkOpenTop(view, unverified).looked);
  OpenTopParams off;
  off.enabled = false;
  EXPECT_FALSE(checkOpenTop(view, chairAt(1.0f), off).covered());
}

TEST(OpenTop, AChairHasABackrest) {
  const VerificationScene view = scene();
  const Hypothesis on_table = chairAt(0.0f, 1.5f);
  const OpenTopCheck table = checkOpenTop(view, on_table);
  EXPECT_GT(table.body, 20) << "the table's top at seat height";
  EXPECT_EQ(table.upper, 0);
  EXPECT_FALSE(table.covered());
  EXPECT_TRUE(table.topless()) << "a chair on a coffee table: nothing where its backrest would be";
  EXPECT_TRUE(table.contradicted());

  OpenTopParams no_upper;
  no_upper.min_upper = 0;
  EXPECT_FALSE(checkOpenTop(view, on_table, no_upper).topless());
  OpenTopParams off;
  off.enabled = false;
  EXPECT_FALSE(checkOpenTop(view, on_table, off).topless());
}

// The rule holds for a category only where each training shape has a top to its body.
TEST(OpenTop, OnlyForCategoriesWhoseShapesHaveAnUpperPart) {
  TrainingObject chair, ottoman;
  plate(chair.surface, -0.25f, 0.25f, -0.25f, 0.25f, 0.45f);
  wall(chair.surface, -0.25f, 0.25f, 0.22f, 0.5f, 0.9f);
  plate(ottoman.surface, -0.3f, 0.3f, -0.3f, 0.3f, 0.4f);
  CategoryModel chairs, ottomans, mixed, shapeless;
  chairs.objects = {chair, chair};
  ottomans.objects = {ottoman};
  mixed.objects = {chair, ottoman};
  shapeless.objects.resize(2);
  EXPECT_TRUE(upperPartTrained(chairs));
  EXPECT_FALSE(upperPartTrained(ottomans));
  EXPECT_FALSE(upperPartTrained(mixed)) << "one shape without it";
  EXPECT_FALSE(upperPartTrained(shapeless));
  OpenTopParams off;
  off.min_upper = 0;
  EXPECT_FALSE(upperPartTrained(chairs, off));
}

// A couch 2 x 0.9 m (a seat at 0.45 m over the front 0.65 m, a back to 0.85 m, arms to 0.65 m) at
// y = -2 m, and a bed 2 x 1.6 m whose mattress is level at 0.6 m at y = 2 m, as a map.
VerificationScene couchAndBed() {
  VerificationScene view;
  view.floor_z = 0.0f;
  view.map = true;
  plate(view.points, -3.0f, 3.0f, -3.5f, 3.5f, 0.0f);
  testing::couchTop(view.points, -2.0f);
  plate(view.points, -1.0f, 1.0f, 1.2f, 2.8f, 0.6f);        // the mattress
  return view;
}

TEST(OpenTop, ACouchIsNotOneLevel) {
  const VerificationScene view = couchAndBed();
  const OpenTopCheck couch = checkOpenTop(view, verifiedCouchAt(-2.0f));
  EXPECT_GT(couch.level_share, 0.4f) << "the seat";
  EXPECT_LT(couch.level_share, 0.6f) << "the back and the arms rise over it";
  EXPECT_FALSE(couch.level());
  EXPECT_FALSE(couch.contradicted());

  // At the bed's foot the mattress fills the top of the body's band and the whole footprint at
  // one level: something stands there, but not a couch.
  const OpenTopCheck bed = checkOpenTop(view, verifiedCouchAt(1.6f));
  EXPECT_GT(bed.upper, 0) << "the mattress at 0.6 m";
  EXPECT_FALSE(bed.contradicted());
  EXPECT_GT(bed.level_share, 0.95f);
  EXPECT_TRUE(bed.level());

  OpenTopParams off;
  off.max_level = 0;
  EXPECT_FALSE(checkOpenTop(view, verifiedCouchAt(1.6f), off).level());
}

// A couch's shape (map_surfaces.h) at y = 0 on the floor, as a map.
VerificationScene couchOnTheFloor() {
  VerificationScene view;
  view.floor_z = 0.0f;
  view.map = true;
  plate(view.points, -3.0f, 3.0f, -3.0f, 3.0f, 0.0f);
  testing::couchTop(view.points, 0.0f);
  return view;
}

// The couch's shape at the foot of a bed seen end on: the footprint holds a seat, a back and arms,
// as a bed's end with its footboard can, but the mattress runs on behind it at 0.55 m. The same
// couch standing free against a wall, with a 1 m coffee table 0.4 m in front of it, is a couch.
TEST(OpenTop, ACouchWhoseSeatHeightSurfaceRunsOnIsRefuted) {
  VerificationScene bed = couchOnTheFloor();
  plate(bed.points, -1.0f, 1.0f, 0.5f, 2.1f, 0.55f);  // the mattress behind the back
  const OpenTopCheck end = checkOpenTop(bed, verifiedCouchAt(0.0f));
  EXPECT_FALSE(end.level()) << "the footprint itself is not one level";
  EXPECT_FALSE(end.contradicted());
  EXPECT_GT(end.run_on_share, 0.95f);
  EXPECT_TRUE(end.runsOn());
  EXPECT_TRUE(end.refuted());

  VerificationScene room = couchOnTheFloor();
  wall(room.points, -3.0f, 3.0f, 0.5f, 0.0f, 2.5f);           // the wall behind its back
  plate(room.points, -0.5f, 0.5f, -1.35f, -0.85f, 0.45f);     // the coffee table's top
  const OpenTopCheck couch = checkOpenTop(room, verifiedCouchAt(0.0f));
  EXPECT_GT(couch.run_on_share, 0.0f) << "the coffee table and the wall fill part of a strip";
  EXPECT_LT(couch.run_on_share, 0.5f);
  EXPECT_FALSE(couch.runsOn());
  EXPECT_FALSE(couch.refuted());

  OpenTopParams off;  // looked at only with the level top
  off.max_level = 0;
  EXPECT_FALSE(checkOpenTop(bed, verifiedCouchAt(0.0f), off).refuted());
  off = {};
  off.max_run_on = 0;
  EXPECT_FALSE(checkOpenTop(bed, verifiedCouchAt(0.0f), off).runsOn());
}

// A tall bed's mattress, level at 0.76 m behind the couch's back (SUN RGB-D's val_000004), lies
// above a seat's height, but runs on as one level: refuted. The level part off, it is not.
TEST(OpenTop, ACouchBeforeATallBedsLevelMattressIsRefuted) {
  VerificationScene bed = couchOnTheFloor();
  plate(bed.points, -1.0f, 1.0f, 0.5f, 2.1f, 0.76f);
  const OpenTopCheck end = checkOpenTop(bed, verifiedCouchAt(0.0f));
  EXPECT_GT(end.run_on_share, 0.95f);
  EXPECT_TRUE(end.refuted());
  OpenTopParams seat_band_only;
  seat_band_only.run_level_to = seat_band_only.run_from;
  const OpenTopCheck seat = checkOpenTop(bed, verifiedCouchAt(0.0f), seat_band_only);
  EXPECT_LT(seat.run_on_share, 0.05f) << "no point at a seat's height past a side";
  EXPECT_FALSE(seat.refuted());
}

// A single view from the origin. Voting put a couch behind a bare wall 2 m ahead, whose face fits a
// couch's back: the wall rises over the side of the box facing the sensor, so the box lies where
// the sensor cannot have seen a couch. A couch before that wall, its back against it, keeps the wall
// over its far side, and a couch seen from behind has nothing over its back.
TEST(OpenTop, ACouchBehindAWallBeforeTheSensorIsContradicted) {
  VerificationScene view;  // the sensor at the origin
  view.floor_z = 0.0f;
  plate(view.points, -3.0f, 3.0f, 0.5f, 2.0f, 0.0f);
  wall(view.points, -3.0f, 3.0f, 2.0f, 0.0f, 2.4f);
  const OpenTopCheck behind = checkOpenTop(view, verifiedCouchAt(2.4f));  // y 1.95-2.85
  EXPECT_GT(behind.near_above, 0);
  EXPECT_GT(behind.nearShare(), 0.3f);
  EXPECT_TRUE(behind.hidden());
  EXPECT_TRUE(behind.contradicted());
  EXPECT_FALSE(behind.covered()) << "the inner part holds no point";

  VerificationScene before = view;
  testing::couchTop(before.points, 1.55f);  // its back at y 1.75-2.0, against the wall
  const OpenTopCheck front = checkOpenTop(before, verifiedCouchAt(1.55f));
  EXPECT_EQ(front.near_above, 0);
  EXPECT_FALSE(front.contradicted());

  VerificationScene away;
  away.floor_z = 0.0f;
  plate(away.points, -3.0f, 3.0f, -4.0f, -0.5f, 0.0f);
  testing::couchTop(away.points, -2.4f);  // its back at y -2.2 to -1.95, facing the sensor
  wall(away.points, -1.0f, 1.0f, -1.97f, 0.1f, 0.8f);  // the back's face
  const OpenTopCheck from_behind = checkOpenTop(away, verifiedCouchAt(-2.4f));
  EXPECT_GT(from_behind.near_body, 0) << "its back";
  EXPECT_FALSE(from_behind.hidden());

  // Not looked at: in a map, whose viewpoint is made up, or switched off.
  VerificationScene map = view;
  map.map = true;
  EXPECT_FALSE(checkOpenTop(map, verifiedCouchAt(2.4f)).hidden());
  OpenTopParams off;
  off.near_edge = 0;
  EXPECT_FALSE(checkOpenTop(view, verifiedCouchAt(2.4f), off).hidden());
}

// A couch's box over a window seat 0.3 m high, the room's wall standing inside the box's back edge,
// in a map (ScanNet's scene0001_00): the only surface in the top of its body is the wall's face,
// which goes on over its top. A couch with its back against the same wall keeps its arms, clear of
// the wall; the clearance off, the wall's face counts as a backrest.
TEST(OpenTop, AWallAtTheEdgeIsNotTheTopOfACouchsBody) {
  VerificationScene seat;
  seat.floor_z = 0.0f;
  seat.map = true;
  plate(seat.points, -3.0f, 3.0f, -3.0f, 0.4f, 0.0f);
  plate(seat.points, -1.0f, 1.0f, -0.45f, 0.4f, 0.3f);  // the window seat
  wall(seat.points, -3.0f, 3.0f, 0.42f, 0.0f, 2.5f);    // the wall, 3 cm inside the box
  const OpenTopCheck on_seat = checkOpenTop(seat, verifiedCouchAt(0.0f));
  EXPECT_FALSE(on_seat.covered()) << "the wall stands outside the inner footprint";
  EXPECT_EQ(on_seat.upper, 0);
  EXPECT_TRUE(on_seat.topless());
  EXPECT_TRUE(on_seat.contradicted());

  OpenTopParams counted;
  counted.upper_clearance = 0;
  const OpenTopCheck face = checkOpenTop(seat, verifiedCouchAt(0.0f), counted);
  EXPECT_GT(face.upper, 10) << "the wall's face from 0.55 to 0.75 m";
  EXPECT_FALSE(face.contradicted());

  VerificationScene room = couchOnTheFloor();  // its back's top at y 0.2-0.45 m, arms to y 0.2 m
  wall(room.points, -3.0f, 3.0f, 0.42f, 0.0f, 2.5f);
  const OpenTopCheck couch = checkOpenTop(room, verifiedCouchAt(0.0f));
  EXPECT_GT(couch.upper, 10) << "the arms' fronts, more than 0.2 m from the wall";
  EXPECT_LT(couch.upper, checkOpenTop(room, verifiedCouchAt(0.0f), counted).upper)
      << "the wall's face and the arms' ends next to it do not count";
  EXPECT_FALSE(couch.contradicted());
}

// A dining chair's training shape 0.5 m square: a seat at 0.45 m, its backrest along +y to 0.9 m.
CategoryModel chairCategory() {
  TrainingObject chair;
  chair.size = {0.5f, 0.5f, 0.9f};
  plate(chair.surface, -0.25f, 0.25f, -0.25f, 0.2f, 0.45f);
  wall(chair.surface, -0.25f, 0.25f, 0.22f, 0.5f, 0.9f);
  CategoryModel category;
  category.objects = {chair};
  return category;
}

TEST(OpenTop, TheBackSideIsWhereTheShapesTopQuarterLies) {
  const TrainingObject chair = chairCategory().objects.front();
  constexpr float kHalfTurn = 3.14159265f;
  EXPECT_EQ(backSide(chair, 0.0f), 2) << "+y";
  EXPECT_EQ(backSide(chair, kHalfTurn / 2), 1) << "+y turned a quarter to -x";
  EXPECT_EQ(backSide(chair, kHalfTurn), 3);
  EXPECT_EQ(backSide(chair, -kHalfTurn / 2), 0);
  EXPECT_EQ(backSide(TrainingObject{}, 0.0f), -1) << "no surface";
}

// The share checkOpenTop finds level behind the back of the shape `hypothesis` was fitted with; 0
// without a fitted shape.
float levelBehindBack(const VerificationScene& scene, const Hypothesis& hypothesis, const CategoryModel& category,
                      const OpenTopParams& params = {}) {
  if (!hypothesis.verification) return 0;
  const int object = hypothesis.verification->object;
  if (object < 0 || static_cast<size_t>(object) >= category.objects.size()) return 0;
  return checkOpenTop(scene, hypothesis, params, &category.objects[static_cast<size_t>(object)]).behind_back_share;
}

// A chair answered on a bench at a bed's foot has the mattress, level at 0.72 m, behind its back:
// refuted. Turned to face the bed, or drawn up to a table whose top (0.74 m) lies before it, the
// strip behind its back is empty, though the table fills the strip before it.
TEST(OpenTop, ALevelSurfaceBehindAChairsBackRefutesIt) {
  const CategoryModel chairs = chairCategory();
  VerificationScene bed;
  bed.floor_z = 0.0f;
  bed.map = true;
  plate(bed.points, -3.0f, 3.0f, -3.0f, 3.0f, 0.0f);
  plate(bed.points, -0.6f, 0.6f, -0.25f, 0.25f, 0.5f);  // the bench
  plate(bed.points, -1.0f, 1.0f, 0.3f, 2.3f, 0.72f);    // the mattress past +y
  Hypothesis chair = chairAt(0.0f);
  chair.verification->object = 0;
  EXPECT_GT(levelBehindBack(bed, chair, chairs), 0.95f);
  Hypothesis facing = chair;
  facing.verification->yaw = 3.14159265f;  // its back to -y
  EXPECT_LT(levelBehindBack(bed, facing, chairs), 0.05f);

  VerificationScene dining;
  dining.floor_z = 0.0f;
  dining.map = true;
  plate(dining.points, -3.0f, 3.0f, -3.0f, 3.0f, 0.0f);
  plate(dining.points, -0.8f, 0.8f, -1.25f, -0.3f, 0.74f);  // the table's top before it
  plate(dining.points, -0.25f, 0.25f, -0.25f, 0.2f, 0.45f);  // the chair
  wall(dining.points, -0.25f, 0.25f, 0.22f, 0.5f, 0.9f);
  EXPECT_LT(levelBehindBack(dining, chair, chairs), 0.05f);
  OpenTopParams level_only;
  level_only.run_to = level_only.run_from;
  std::vector<Eigen::Vector3f> beside;
  for (const auto& p : dining.points) {
    if (std::abs(p.x()) > 0.25f || std::abs(p.y()) > 0.25f) beside.push_back(p);
  }
  EXPECT_GT(runOnShare(beside, 0.5f, 0.5f, level_only), 0.8f) << "the table's top fills the strip before it";

  // Not looked at: no fitted shape, switched off.
  EXPECT_EQ(levelBehindBack(bed, chairAt(0.0f), chairs), 0.0f);
  OpenTopParams off;
  off.behind_back = false;
  EXPECT_EQ(levelBehindBack(bed, chair, chairs, off), 0.0f);
}

// The level part counts the cells whose highest point below the cap lies in one band: two levels
// fill a strip by halves, a wall's cells reach the cap and fill none.
TEST(OpenTop, TheRunOnShareOfALevelSurfaceTakesOneBand) {
  std::vector<Eigen::Vector3f> tall;  // the strip past -x of a 2 x 1 m footprint, at 0.76 m
  plate(tall, -1.54f, -1.06f, -0.38f, 0.38f, 0.76f);
  EXPECT_NEAR(runOnShare(tall, 2.0f, 1.0f), 1.0f, 0.05f);
  std::vector<Eigen::Vector3f> steps;  // half of it at 0.76 m, half at 0.5 m
  plate(steps, -1.54f, -1.06f, -0.38f, -0.02f, 0.76f);
  plate(steps, -1.54f, -1.06f, 0.02f, 0.38f, 0.5f);
  OpenTopParams level_only;
  level_only.run_to = level_only.run_from;
  EXPECT_NEAR(runOnShare(steps, 2.0f, 1.0f, level_only), 0.5f, 0.1f);
  EXPECT_NEAR(runOnShare(steps, 2.0f, 1.0f), 0.5f, 0.1f) << "the seat's band holds the lower half";
  std::vector<Eigen::Vector3f> walls = tall;  // walls across the strip, every 10 cm out
  for (float x = -1.5f; x < -1.05f; x += 0.1f) {
    for (float y = -0.38f; y <= 0.38f; y += 0.05f) {
      for (float z = 0.0f; z < 2.0f; z += 0.05f) walls.emplace_back(x, y, z);
    }
  }
  EXPECT_LT(runOnShare(walls, 2.0f, 1.0f, level_only), 0.05f);
}

TEST(OpenTop, TheRunOnShareCountsTheFullestStrip) {
  std::vector<Eigen::Vector3f> points;  // beside a 2 x 1 m footprint: half of the strip past +y
  plate(points, 0.0f, 0.78f, 0.56f, 1.04f, 0.5f);
  EXPECT_NEAR(runOnShare(points, 2.0f, 1.0f), 0.5f, 0.1f);
  plate(points, -1.54f, -1.06f, -0.38f, 0.38f, 0.5f);  // all of the strip past -x
  const float nan = std::numeric_limits<float>::quiet_NaN();
  points.emplace_back(nan, nan, 0.5f);  // lies in no strip
  EXPECT_NEAR(runOnShare(points, 2.0f, 1.0f), 1.0f, 0.05f);
  std::vector<Eigen::Vector3f> high;  // over the band: a shelf at 1 m
  plate(high, -1.54f, -1.06f, -0.38f, 0.38f, 1.0f);
  EXPECT_EQ(runOnShare(high, 2.0f, 1.0f), 0.0f);
}

TEST(OpenTop, TheLevelShareCountsTheFootprintsCells) {
  std::vector<Eigen::Vector3f> half;  // a level plate over one half of a 1 m square, none on the other
  plate(half, -0.48f, -0.02f, -0.48f, 0.48f, 0.5f);
  EXPECT_NEAR(levelShare(half, 1.0f, 1.0f, 0.8f), 0.5f, 0.1f);
  std::vector<Eigen::Vector3f> steps = half;  // the other half a step higher
  plate(steps, 0.02f, 0.48f, -0.48f, 0.48f, 0.7f);
  EXPECT_NEAR(levelShare(steps, 1.0f, 1.0f, 0.8f), 0.5f, 0.1f);
  std::vector<Eigen::Vector3f> slope = half;  // within one band: one level
  plate(slope, 0.02f, 0.48f, -0.48f, 0.48f, 0.55f);
  EXPECT_GT(levelShare(slope, 1.0f, 1.0f, 0.8f), 0.95f);
  // Points outside the footprint, on the floor or far over the top are not looked at.
  std::vector<Eigen::Vector3f> outside;
  plate(outside, 0.6f, 1.0f, -0.48f, 0.48f, 0.5f);
  plate(outside, -0.48f, 0.48f, -0.48f, 0.48f, 0.05f);
  plate(outside, -0.48f, 0.48f, -0.48f, 0.48f, 1.2f);
  EXPECT_EQ(levelShare(outside, 1.0f, 1.0f, 0.8f), 0.0f);
}

// The level top is looked at only for categories none of whose training shapes is that level.
TEST(OpenTop, LevelTopsOnlyForCategoriesWhoseShapesRiseOverTheSeat) {
  TrainingObject couch, chair, ottoman;
  couch.size = {2.0f, 0.9f, 0.85f};
  testing::couchTop(couch.surface, 0.0f);
  chair.size = {0.5f, 0.5f, 0.9f};  // the seat covers most of a chair's footprint
  plate(chair.surface, -0.25f, 0.25f, -0.25f, 0.17f, 0.45f);
  plate(chair.surface, -0.25f, 0.25f, 0.17f, 0.25f, 0.9f);
  ottoman.size = {0.6f, 0.6f, 0.4f};
  plate(ottoman.surface, -0.3f, 0.3f, -0.3f, 0.3f, 0.4f);
  CategoryModel couches, chairs, mixed, shapeless;
  couches.objects = {couch, couch};
  chairs.objects = {chair};
  mixed.objects = {couch, ottoman};
  shapeless.objects.resize(2);
  EXPECT_TRUE(stepTopTrained(couches));
  EXPECT_FALSE(stepTopTrained(chairs));
  EXPECT_FALSE(stepTopTrained(mixed)) << "one shape is level";
  EXPECT_FALSE(stepTopTrained(shapeless));
  OpenTopParams off;
  off.max_level = 0;
  EXPECT_FALSE(stepTopTrained(couches, off));
}

}  // namespace
}  // namespace ism
