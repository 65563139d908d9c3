// An open top: a chair standing free, the same chair under a wall cabinet, and a coffee table.
#include "core/recognition/open_top.h"

#include <vector>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "core/common/upright_box.h"
#include "tests/common/verified_hypothesis.h"

namespace ism {
namespace {

// Points every 5 cm on the horizontal rectangle [x0, x1] x [y0, y1] at height z, or on the
// vertical one [x0, x1] x [z0, z1] at depth y: a map's surface.
void plate(std::vector<Eigen::Vector3f>& points, float x0, float x1, float y0, float y1, float z) {
  for (float x = x0; x <= x1 + 1e-4f; x += 0.05f) {
    for (float y = y0; y <= y1 + 1e-4f; y += 0.05f) points.emplace_back(x, y, z);
  }
}
void wall(std::vector<Eigen::Vector3f>& points, float x0, float x1, float y, float z0, float z1) {
  for (float x = x0; x <= x1 + 1e-4f; x += 0.05f) {
    for (float z = z0; z <= z1 + 1e-4f; z += 0.05f) points.emplace_back(x, y, z);
  }
}

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

}  // namespace
}  // namespace ism
