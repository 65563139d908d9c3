// Under the top: a table on legs with the floor seen beneath it, and a cabinet as deep and as high,
// closed all round, whose top hides everything under it.
#include "core/recognition/under_top.h"

#include <vector>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "core/common/upright_box.h"
#include "tests/common/map_surfaces.h"
#include "tests/common/verified_hypothesis.h"

namespace ism {
namespace {

using testing::plate;
using testing::wall;

// The floor everywhere but under the cabinet; a table's top 1.2 x 0.8 m at 0.75 m at x = -1 m on
// four legs; a cabinet 1.2 x 0.8 m, 0.75 m high, at x = 1 m, its front and back walls down to the
// floor (its ends too, as a map sees them).
VerificationScene scene() {
  VerificationScene view;
  view.floor_z = 0.0f;
  view.map = true;
  plate(view.points, -3.0f, 0.4f, -2.0f, 2.0f, 0.0f);
  plate(view.points, 0.4f, 3.0f, -2.0f, -0.4f, 0.0f);
  plate(view.points, 0.4f, 3.0f, 0.4f, 2.0f, 0.0f);
  plate(view.points, 1.6f, 3.0f, -0.4f, 0.4f, 0.0f);
  plate(view.points, -1.6f, -0.4f, -0.4f, 0.4f, 0.75f);  // the table's top
  for (const float x : {-1.55f, -0.45f}) {
    for (const float y : {-0.35f, 0.35f}) wall(view.points, x - 0.02f, x + 0.02f, y, 0.0f, 0.72f);  // a leg
  }
  plate(view.points, 0.4f, 1.6f, -0.4f, 0.4f, 0.75f);  // the cabinet's top
  wall(view.points, 0.4f, 1.6f, -0.4f, 0.0f, 0.75f);
  wall(view.points, 0.4f, 1.6f, 0.4f, 0.0f, 0.75f);
  for (float y = -0.4f; y <= 0.4f; y += 0.05f) {
    for (float z = 0.0f; z <= 0.75f; z += 0.05f) {
      view.points.emplace_back(0.4f, y, z);
      view.points.emplace_back(1.6f, y, z);
    }
  }
  return view;
}

Hypothesis tableAt(float x) { return testing::verifiedStandingAt("dining_table", {1.2f, 0.8f, 0.75f}, x, 0.0f); }

TEST(UnderTop, ATableIsOpenUnderneathACabinetIsNot) {
  const VerificationScene view = scene();
  const UnderTopCheck table = checkUnderTop(view, tableAt(-1.0f));
  EXPECT_TRUE(table.looked);
  EXPECT_GT(table.open, 0.9f) << "the floor is seen under the table";
  EXPECT_FALSE(table.closed());
  const UnderTopCheck cabinet = checkUnderTop(view, tableAt(1.0f));
  EXPECT_LT(cabinet.open, 0.05f) << "its sides stay out of the inner footprint";
  EXPECT_TRUE(cabinet.closed());
  UnderTopParams off;
  off.enabled = false;
  EXPECT_FALSE(checkUnderTop(view, tableAt(1.0f), off).closed());
  Hypothesis unverified = tableAt(1.0f);
  unverified.verification.reset();
  EXPECT_FALSE(checkUnderTop(view, unverified).looked);
}

// A single view from the origin looking along +y: a dresser 1.2 x 0.45 m, 0.8 m high, 2 m ahead,
// whose front of drawers faces the sensor; the box it was answered with as a table reaches 0.15 m
// in front of that face (the fitted shape and the measured top do not meet exactly), so the
// drawers lie inside the inner footprint. Behind them the sensor sees nothing under the top.
// A table as big beside it shows the floor under its top beyond its near edge.
TEST(UnderTop, ADressersFrontFacingTheSensorDoesNotOpenIt) {
  VerificationScene view;  // the sensor at the origin
  view.floor_z = 0.0f;
  plate(view.points, -3.0f, 3.0f, 0.5f, 1.85f, 0.0f);    // the floor before both
  plate(view.points, -0.6f, 0.6f, 1.85f, 2.3f, 0.8f);    // the dresser's top
  wall(view.points, -0.6f, 0.6f, 1.85f, 0.0f, 0.8f);     // its drawers
  plate(view.points, -2.6f, -1.4f, 1.85f, 2.6f, 0.0f);   // the floor under the table
  plate(view.points, -2.6f, -1.4f, 1.85f, 2.3f, 0.8f);   // the table's top
  for (const float x : {-2.55f, -1.45f}) wall(view.points, x - 0.02f, x + 0.02f, 1.9f, 0.0f, 0.77f);  // legs
  const auto answeredAt = [](float x) {
    return testing::verifiedStandingAt("dining_table", {1.2f, 0.6f, 0.8f}, x, 2.0f);  // y 1.7-2.3
  };
  const UnderTopCheck dresser = checkUnderTop(view, answeredAt(0.0f));
  EXPECT_LT(dresser.open, 0.05f);
  EXPECT_TRUE(dresser.closed());
  UnderTopParams all_count;
  all_count.near_edge = 0;
  EXPECT_FALSE(checkUnderTop(view, answeredAt(0.0f), all_count).closed()) << "the drawers, counted";
  const UnderTopCheck table = checkUnderTop(view, answeredAt(-2.0f));
  EXPECT_GT(table.open, 0.3f) << "the floor beyond the near edge";
  EXPECT_FALSE(table.closed());
  VerificationScene map = view;  // a map's viewpoint is made up: every point counts
  map.map = true;
  EXPECT_FALSE(checkUnderTop(map, answeredAt(0.0f)).closed());
}

TEST(UnderTop, TheOpenShareCountsTheInnerFootprintsCells) {
  std::vector<Eigen::Vector3f> half;  // floor under one half of a 1 m square, at 0.8 m high
  plate(half, -0.5f, -0.05f, -0.5f, 0.5f, 0.0f);
  EXPECT_NEAR(openUnderShare(half, 1.0f, 1.0f, 0.8f), 0.5f, 0.1f);
  std::vector<Eigen::Vector3f> top;  // the top and its apron are not under it
  plate(top, -0.5f, 0.5f, -0.5f, 0.5f, 0.8f);
  plate(top, -0.5f, 0.5f, -0.5f, 0.5f, 0.7f);
  EXPECT_EQ(openUnderShare(top, 1.0f, 1.0f, 0.8f), 0.0f);
  std::vector<Eigen::Vector3f> rim;  // a block's sides, outside the inner footprint
  wall(rim, -0.5f, 0.5f, -0.5f, 0.0f, 0.8f);
  wall(rim, -0.5f, 0.5f, 0.5f, 0.0f, 0.8f);
  EXPECT_EQ(openUnderShare(rim, 1.0f, 1.0f, 0.8f), 0.0f);
}

}  // namespace
}  // namespace ism
