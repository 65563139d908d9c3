// A seat's area: a couch shows its seat over its footprint; a desk as long and as deep, on two
// legs and a drawer front, shows a line of parts at seat height and nothing between them.
#include "core/recognition/seat_area.h"

#include <vector>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "core/common/upright_box.h"
#include "tests/common/map_surfaces.h"
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
