// A seat under a table's top: a couch along a table's side, a chair pushed under it, a couch
// beside a low table, and which of two answers goes.
#include "core/recognition/seat_under_top.h"

#include <gtest/gtest.h>

#include "tests/common/synthetic_furniture.h"
#include "tests/common/verified_hypothesis.h"

namespace ism {
namespace {

using testing::verifiedStandingAt;

// A category of one training shape: the surface of the boxes `parts` (lo, hi), of `size`.
CategoryModel category(const std::string& name, const Eigen::Vector3f& size,
                       const std::vector<std::pair<Eigen::Vector3f, Eigen::Vector3f>>& parts) {
  CategoryModel c;
  c.name = name;
  TrainingObject object;
  object.size = size;
  object.center_height = size.z() / 2;
  for (const auto& [lo, hi] : parts) {
    for (const auto& p : testing::boxSurface(lo, hi)) object.surface.push_back(p);
  }
  c.objects.push_back(object);
  return c;
}

TEST(SeatUnderTop, ACategoryIsATopALongSeatOrNeither) {
  const TopExtentParams top;
  const SeatRunParams seat;
  // A table: a 1.2 x 0.8 m top 0.72-0.76 m high on one leg; a couch 1.8 m long; a chair 0.5 m wide.
  const CategoryModel table =
      category("dining_table", {1.2f, 0.8f, 0.76f},
               {{{-0.6f, -0.4f, 0.72f}, {0.6f, 0.4f, 0.76f}}, {{-0.04f, -0.04f, 0}, {0.04f, 0.04f, 0.72f}}});
  const CategoryModel couch =
      category("couch", {1.8f, 0.9f, 0.85f},
               {{{-0.9f, -0.45f, 0}, {0.9f, 0.45f, 0.45f}}, {{-0.9f, 0.3f, 0.45f}, {0.9f, 0.45f, 0.85f}}});
  const CategoryModel chair =
      category("dining_chair", {0.5f, 0.5f, 0.9f},
               {{{-0.25f, -0.25f, 0.4f}, {0.25f, 0.25f, 0.45f}}, {{-0.25f, 0.2f, 0.45f}, {0.25f, 0.25f, 0.9f}}});
  EXPECT_EQ(floorKind(table, top, seat), FloorKind::kTop);
  EXPECT_EQ(floorKind(couch, top, seat), FloorKind::kLongSeat);
  EXPECT_EQ(floorKind(chair, top, seat), FloorKind::kOther) << "a chair's seat runs 0.5 m";
  EXPECT_EQ(floorKind(CategoryModel{}, top, seat), FloorKind::kOther) << "no training shapes";
  SeatUnderTopParams longer;
  longer.long_seat = 2.0f;
  EXPECT_EQ(floorKind(couch, top, seat, longer), FloorKind::kOther) << "shorter than asked";
}

FloorKind kindOf(const std::string& name) {
  if (name == "dining_table") return FloorKind::kTop;
  if (name == "couch") return FloorKind::kLongSeat;
  return FloorKind::kOther;
}

// A 1.6 x 1.0 m table's box, 0.75 m high, centred on the origin, and answers beside it.
Hypothesis answer(const std::string& name, const Eigen::Vector3f& size, float x, float y, float confidence) {
  Hypothesis h = verifiedStandingAt(name, size, x, y);
  h.confidence = confidence;
  return h;
}
Hypothesis table(float confidence) { return answer("dining_table", {1.6f, 1.0f, 0.75f}, 0, 0, confidence); }
// A 2.0 x 0.8 m couch along the table's long side, `under` m of its depth under the top.
Hypothesis couchAlong(float under, float confidence) {
  return answer("couch", {2.0f, 0.8f, 0.85f}, 0, 0.5f + 0.4f - under, confidence);
}

std::vector<std::string> names(const std::vector<Hypothesis>& hs) {
  std::vector<std::string> out;
  for (const auto& h : hs) out.push_back(h.category);
  return out;
}

TEST(SeatUnderTop, OfACouchAndATableOverAThirdOfItsFootprintTheLessConfidentGoes) {
  const Eigen::Matrix3f up = Eigen::Matrix3f::Identity();
  // Half the couch's depth under the top, 0.8 of its 2 m length: 0.4 of its footprint.
  std::vector<Hypothesis> answers{table(0.9f), couchAlong(0.4f, 0.7f)};
  std::vector<Hypothesis> dropped;
  dropSeatsUnderTops(answers, kindOf, up, {}, dropped);
  EXPECT_EQ(names(answers), std::vector<std::string>{"dining_table"});
  ASSERT_EQ(names(dropped), std::vector<std::string>{"couch"});
  EXPECT_FALSE(dropped[0].passed_selection);

  answers = {couchAlong(0.4f, 0.8f), table(0.5f)};
  dropped.clear();
  dropSeatsUnderTops(answers, kindOf, up, {}, dropped);
  EXPECT_EQ(names(answers), std::vector<std::string>{"couch"}) << "the more confident couch stays";
  EXPECT_EQ(names(dropped), std::vector<std::string>{"dining_table"});
}

TEST(SeatUnderTop, ChairsUnderTheTopAndCouchesBesideItStay) {
  const Eigen::Matrix3f up = Eigen::Matrix3f::Identity();
  std::vector<Hypothesis> dropped;
  // A chair pushed all the way under; a couch with 0.1 m of its 0.8 m depth under (1/8 of it); a
  // couch on the other side 0.3 m away.
  std::vector<Hypothesis> answers{table(0.9f), answer("dining_chair", {0.5f, 0.5f, 0.9f}, 0.5f, 0.3f, 0.6f),
                                  couchAlong(0.1f, 0.7f), answer("couch", {2.0f, 0.8f, 0.85f}, 0, -1.2f, 0.5f)};
  dropSeatsUnderTops(answers, kindOf, up, {}, dropped);
  EXPECT_EQ(answers.size(), 4u);
  EXPECT_TRUE(dropped.empty());
}

TEST(SeatUnderTop, RefutedUnverifiedOrSwitchedOffDropsNothing) {
  const Eigen::Matrix3f up = Eigen::Matrix3f::Identity();
  std::vector<Hypothesis> dropped;
  Hypothesis refuted = table(0.9f);
  refuted.refuted = true;
  std::vector<Hypothesis> answers{refuted, couchAlong(0.4f, 0.7f)};
  dropSeatsUnderTops(answers, kindOf, up, {}, dropped);
  EXPECT_EQ(answers.size(), 2u) << "a refuted table takes no couch's place";

  Hypothesis unverified = couchAlong(0.4f, 0.7f);
  unverified.verification.reset();
  answers = {table(0.9f), unverified};
  dropSeatsUnderTops(answers, kindOf, up, {}, dropped);
  EXPECT_EQ(answers.size(), 2u) << "an unverified couch's box is no fitted shape's";

  SeatUnderTopParams off;
  off.enabled = false;
  answers = {table(0.9f), couchAlong(0.4f, 0.7f)};
  dropSeatsUnderTops(answers, kindOf, up, off, dropped);
  EXPECT_EQ(answers.size(), 2u);
  EXPECT_TRUE(dropped.empty());

  // A couch turned a quarter about up at the table's short side: its 0.8 m depth along x, 0.6 m of
  // it under the top over the table's 1.0 m width, 0.375 of its footprint.
  UprightBox box;
  box.size = {2.0f, 0.8f, 0.85f};
  box.center = {0.8f + 0.4f - 0.6f, 0, 0.425f};
  box.yaw = 1.5707963f;
  Hypothesis turned = testing::verifiedHypothesis("couch", box);
  turned.confidence = 0.7f;
  answers = {table(0.9f), turned};
  dropSeatsUnderTops(answers, kindOf, up, {}, dropped);
  EXPECT_EQ(names(answers), std::vector<std::string>{"dining_table"});
  turned.box = UprightBox{{0.8f + 0.4f - 0.4f, 0, 0.425f}, box.size, box.yaw}.toScene(up);
  answers = {table(0.9f), turned};
  dropSeatsUnderTops(answers, kindOf, up, {}, dropped);
  EXPECT_EQ(answers.size(), 2u) << "0.4 m of its depth under: 0.25 of its footprint";
}

}  // namespace
}  // namespace ism
