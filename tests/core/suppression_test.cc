// One answer per object (suppression.h): which hypotheses merge, and which stay apart.
#include "core/recognition/suppression.h"

#include <gtest/gtest.h>

#include <numeric>

#include "core/common/upright_box.h"

namespace ism {
namespace {

// z up: the scene is its own gravity frame.
const Eigen::Matrix3f kUp = Eigen::Matrix3f::Identity();

// Surface cells first..first+count-1, as verification would list them.
std::vector<uint64_t> cells(uint64_t first, size_t count) {
  std::vector<uint64_t> out(count);
  std::iota(out.begin(), out.end(), first);
  return out;
}

Hypothesis hypothesis(const std::string& category, float confidence, const Eigen::Vector3f& center,
                      const Eigen::Vector3f& size, std::optional<std::vector<uint64_t>> explained = std::nullopt) {
  Hypothesis h;
  h.category = category;
  h.confidence = confidence;
  h.center = center;
  UprightBox box;
  box.center = center;
  box.size = size;
  h.box = box.toScene(kUp);
  h.upright_box = true;
  if (explained) {
    h.verification = Verification{};
    h.verification->explained = *explained;
  }
  return h;
}

// A desk 1.4 x 0.7 x 0.75 m and a chair pushed under its front edge: the chair's centre is in the
// desk's footprint, their boxes overlap by far less than 0.25.
const Eigen::Vector3f kDeskCentre(0, 0, 0.375f), kDeskSize(1.4f, 0.7f, 0.75f);
const Eigen::Vector3f kChairCentre(0.2f, 0.3f, 0.45f), kChairSize(0.5f, 0.5f, 0.9f);

TEST(Suppression, TheBoxesOfTheTestSceneOverlapLittle) {
  UprightBox desk{kDeskCentre, kDeskSize, 0}, chair{kChairCentre, kChairSize, 0};
  EXPECT_LT(intersectionOverUnion(desk, chair), 0.25f);
}

TEST(Suppression, AChairUnderADeskThatExplainsOtherSurfaceIsAnObjectOfItsOwn) {
  std::vector<Hypothesis> hs = {hypothesis("chair", 0.3f, kChairCentre, kChairSize, cells(1000, 40)),
                                hypothesis("desk", 0.6f, kDeskCentre, kDeskSize, cells(0, 100))};
  const auto kept = suppressOverlaps(hs, kUp);
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_EQ(kept[0].category, "desk");  // most confident first
  EXPECT_EQ(kept[1].category, "chair");
  EXPECT_TRUE(kept[0].alternatives.empty());
}

TEST(Suppression, AChairPeakOnTheDesksOwnSurfaceIsTheDeskAndStaysAsItsAlternative) {
  // 30 of the chair's 40 cells are the desk's.
  std::vector<Hypothesis> hs = {hypothesis("chair", 0.3f, kChairCentre, kChairSize, cells(70, 40)),
                                hypothesis("desk", 0.6f, kDeskCentre, kDeskSize, cells(0, 100))};
  const auto kept = suppressOverlaps(hs, kUp);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].category, "desk");
  ASSERT_EQ(kept[0].alternatives.size(), 1u);
  EXPECT_EQ(kept[0].alternatives[0].category, "chair");
  EXPECT_FLOAT_EQ(kept[0].alternatives[0].confidence, 0.3f);
}

TEST(Suppression, UnverifiedHypothesesWithACentreInTheOthersFootprintAreOneObject) {
  std::vector<Hypothesis> hs = {hypothesis("chair", 0.3f, kChairCentre, kChairSize),
                                hypothesis("desk", 0.6f, kDeskCentre, kDeskSize)};
  EXPECT_EQ(suppressOverlaps(hs, kUp).size(), 1u);
}

TEST(Suppression, PeaksOfOneCategoryMergeByCentreWhateverTheySee) {
  // A long table's two peaks, 0.5 m apart: small overlap, each centre inside the other's footprint.
  const Eigen::Vector3f size(1.2f, 0.6f, 0.75f);
  std::vector<Hypothesis> hs = {hypothesis("table", 0.5f, {0, 0, 0.375f}, size, cells(0, 50)),
                                hypothesis("table", 0.4f, {0.5f, 0, 0.375f}, size, cells(500, 50))};
  const auto kept = suppressOverlaps(hs, kUp);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_FLOAT_EQ(kept[0].confidence, 0.5f);
  EXPECT_TRUE(kept[0].alternatives.empty());
}

// Keypoints `indices` at x = index / 10 m, as the Hough space lists a peak's support.
void support(Hypothesis& h, const std::vector<int>& indices) {
  h.support_indices = indices;
  h.support_keypoints.clear();
  h.support_centroid.setZero();
  for (int k : indices) {
    h.support_keypoints.emplace_back(0.1f * static_cast<float>(k), 0, 0.75f);
    h.support_centroid += h.support_keypoints.back();
  }
  h.support = static_cast<int>(indices.size());
  h.support_centroid /= static_cast<float>(h.support);
}

TEST(Suppression, OneAnswerOnALongTableIsSupportedByEveryPeakItsTopGave) {
  const Eigen::Vector3f size(1.2f, 0.6f, 0.75f);
  std::vector<Hypothesis> hs = {hypothesis("table", 0.5f, {0, 0, 0.375f}, size),
                                hypothesis("table", 0.4f, {0.5f, 0, 0.375f}, size)};
  support(hs[0], {0, 1, 2, 3});
  support(hs[1], {2, 3, 8, 9});  // keypoints 2 and 3 voted into both peaks
  auto kept = suppressOverlaps(hs, kUp);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].support_indices, (std::vector<int>{0, 1, 2, 3, 8, 9}));
  EXPECT_EQ(kept[0].support, 6);
  ASSERT_EQ(kept[0].support_keypoints.size(), 6u);
  EXPECT_FLOAT_EQ(kept[0].support_keypoints[4].x(), 0.8f);
  EXPECT_NEAR(kept[0].support_centroid.x(), 0.1f * 23 / 6, 1e-5f);

  // Before the confidence is made from each peak's own support, the winner keeps its own.
  SuppressionParams params;
  params.merge_support = false;
  kept = suppressOverlaps(hs, kUp, params);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].support, 4);
  EXPECT_NEAR(kept[0].support_centroid.x(), 0.15f, 1e-5f);
}

TEST(Suppression, AnotherCategorysPeakLendsNoSupport) {
  std::vector<Hypothesis> hs = {hypothesis("office_chair", 0.4f, {0, 0, 0.45f}, kChairSize),
                                hypothesis("dining_chair", 0.2f, {0.1f, 0, 0.45f}, kChairSize)};
  support(hs[0], {0, 1});
  support(hs[1], {5, 6});
  const auto kept = suppressOverlaps(hs, kUp);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].support_indices, (std::vector<int>{0, 1}));
  EXPECT_EQ(kept[0].support, 2);
}

TEST(Suppression, BoxesOverlappingByAQuarterAreOneObjectWhateverTheySee) {
  // An office chair and a dining chair on one chair, 10 cm apart, explaining different cells.
  std::vector<Hypothesis> hs = {hypothesis("office_chair", 0.4f, {0, 0, 0.45f}, kChairSize, cells(0, 40)),
                                hypothesis("dining_chair", 0.2f, {0.1f, 0, 0.45f}, kChairSize, cells(100, 40))};
  const auto kept = suppressOverlaps(hs, kUp);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].category, "office_chair");
  ASSERT_EQ(kept[0].alternatives.size(), 1u);
  EXPECT_EQ(kept[0].alternatives[0].category, "dining_chair");
}

TEST(Suppression, ObjectsApartAreAllKept) {
  std::vector<Hypothesis> hs = {hypothesis("chair", 0.4f, {0, 0, 0.45f}, kChairSize),
                                hypothesis("chair", 0.3f, {1, 0, 0.45f}, kChairSize),
                                hypothesis("desk", 0.2f, {3, 0, 0.375f}, kDeskSize)};
  EXPECT_EQ(suppressOverlaps(hs, kUp).size(), 3u);
}

// A refuted hypothesis (a couch on a bed's level top) keeps its object from the others' answers
// but is no one's alternative.
TEST(Suppression, ARefutedHypothesisKeepsItsObjectButIsNoAlternative) {
  Hypothesis couch = hypothesis("couch", 0.8f, kDeskCentre, kDeskSize, cells(0, 100));
  couch.refuted = true;
  const Hypothesis table = hypothesis("table", 0.5f, kDeskCentre, kDeskSize, cells(0, 100));
  auto kept = suppressOverlaps({couch, table}, kUp);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_TRUE(kept[0].refuted) << "the table stands on the same object";
  ASSERT_EQ(kept[0].alternatives.size(), 1u);
  EXPECT_EQ(kept[0].alternatives[0].category, "table");

  couch.confidence = 0.3f;
  kept = suppressOverlaps({couch, table}, kUp);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].category, "table");
  EXPECT_TRUE(kept[0].alternatives.empty()) << "a refuted couch is not the table's alternative";
}

}  // namespace
}  // namespace ism
