// The calibration's logistic fit: the confidence follows whichever of score and verification fit
// tells positives from negatives. Its rooms: the held-out furniture among walls, boxes and
// background furniture.
#include "core/training/calibration.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "core/common/error.h"
#include "core/gravity/viewpoint.h"
#include "core/recognition/recognizer.h"
#include "tests/common/synthetic_furniture.h"

namespace ism {
namespace {

TEST(FitCalibration, TheFitDecidesWhereTheScoreCannot) {
  // Scores drawn alike for both; positives fit the scene (0.7-1.0), negatives do not (0.1-0.6).
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> score(0.05f, 2.0f), good(0.7f, 1.0f), bad(0.1f, 0.6f);
  std::vector<CalibrationSample> samples;
  for (int i = 0; i < 400; ++i) {
    const bool positive = i % 4 == 0;
    samples.push_back({0, score(rng), 10, positive, positive ? good(rng) : bad(rng)});
  }
  const Calibration fit = fitCalibration(samples);
  EXPECT_GT(fit.d, 5.0f);
  EXPECT_GT(fit.confidence(0.5f, 10, 0.9f), 0.9f);
  EXPECT_LT(fit.confidence(0.5f, 10, 0.3f), 0.1f);
  EXPECT_EQ(fit.positives, 100);
  EXPECT_EQ(fit.negatives, 300);
}

TEST(FitCalibration, UnverifiedSamplesLeaveTheFitOutOfIt) {
  // Every sample unverified (fit 0.5): the score alone separates, and the fit term cannot matter.
  std::vector<CalibrationSample> samples;
  for (int i = 0; i < 200; ++i) {
    const bool positive = i % 2 == 0;
    samples.push_back({0, positive ? 1.0f + 0.01f * static_cast<float>(i) : 0.1f + 0.001f * static_cast<float>(i), 8,
                       positive, 0.5f});
  }
  const Calibration fit = fitCalibration(samples);
  EXPECT_GT(fit.a + fit.c, 0.0f);
  EXPECT_GT(fit.confidence(2.0f, 8), 0.9f);
  EXPECT_LT(fit.confidence(0.15f, 8), 0.1f);
  EXPECT_NEAR(fit.confidence(0.5f, 8, 0.5f), fit.confidence(0.5f, 8), 1e-6f);
}

TEST(FitCalibration, NeedsBothKinds) {
  EXPECT_THROW(fitCalibration({{0, 1.0f, 3, true, 0.9f}}), Error);
}

// Whether the room shows the test's bed, a clutter object of its footprint, 1.9 m x 1.4 m: no
// wall or box of a room has it (boxes are at most 1.2 m x 0.6 m).
bool holdsBed(const CalibrationRoom& room) {
  for (const GroundTruthObject& o : room.scene.objects) {
    if (o.category.empty() && std::abs(o.size.x() - 1.9f) < 0.01f && std::abs(o.size.y() - 1.4f) < 0.01f &&
        o.points > 0) {
      return true;
    }
  }
  return false;
}

// The confidence is learned on the rooms' peaks as recognition finds them: a peak centred on its
// 27 bins' votes scores higher than one centred on its bin's, the false ones too.
TEST(CalibrationParams, CentresTheRoomsPeaksOnTheirNeighbourhood) {
  EXPECT_EQ(CalibrationParams{}.peak_centre, PeakCentre::kNeighbourhood);
  EXPECT_EQ(CalibrationParams{}.fit_terms, FitTerms::kBoth);
}

TEST(CategoryKind, IsTheLastWordOfTheName) {
  EXPECT_EQ(categoryKind("office_chair"), "chair");
  EXPECT_EQ(categoryKind("dining_chair"), "chair");
  EXPECT_EQ(categoryKind("dining_table"), "table");
  EXPECT_EQ(categoryKind("couch"), "couch");
  EXPECT_EQ(categoryKind("low_side_table"), "table");
}

// A room seen with z up: an office chair, a dining chair, a table and a box of clutter, 2 m apart.
struct LabelRoom {
  std::vector<std::string> categories{"office_chair", "dining_chair", "dining_table", ""};
  std::vector<GroundTruthObject> objects{
      {"office_chair", {0, 0, 0.45f}, {0.6f, 0.6f, 0.9f}, 0, 0},
      {"dining_chair", {2, 0, 0.45f}, {0.45f, 0.5f, 0.9f}, 0, 0},
      {"dining_table", {0, 2, 0.37f}, {1.6f, 0.8f, 0.75f}, 0, 0},
      {"", {-2, 0, 0.3f}, {0.6f, 0.6f, 0.6f}, 0, 0}};
  std::vector<bool> matched = std::vector<bool>(4, false);

  PeakLabel label(const Eigen::Vector3f& at, bool kinds = true) {
    Hypothesis peak;
    peak.category = "dining_chair";
    peak.center = at;
    peak.box.center = at;
    peak.box.size = {0.45f, 0.5f, 0.9f};
    return labelPeak(peak, categories, objects, Eigen::Matrix3f::Identity(), kinds, matched);
  }
};

TEST(LabelPeak, APeakOnAChairOfTheOtherKindIsLeftOutNotCountedAgainst) {
  LabelRoom room;
  EXPECT_EQ(room.label({0.05f, 0.02f, 0.45f}), PeakLabel::kLeftOut) << "a dining chair's peak on the office chair";
  EXPECT_EQ(room.label({0.05f, 0.02f, 0.45f}, false), PeakLabel::kNegative) << "counted against, as the seed's rooms";
  EXPECT_EQ(room.label({0, 2, 0.45f}), PeakLabel::kNegative) << "on the table: another kind";
  EXPECT_EQ(room.label({-2, 0, 0.45f}), PeakLabel::kNegative) << "on the clutter";
  EXPECT_EQ(room.label({1, 0, 0.45f}), PeakLabel::kNegative) << "between the chairs, on neither";
  EXPECT_EQ(room.matched, std::vector<bool>(4, false)) << "only a positive takes its object";
}

TEST(LabelPeak, TheFirstPeakOnAnObjectOfItsCategoryIsPositiveASecondNegative) {
  LabelRoom room;
  EXPECT_EQ(room.label({2.05f, 0, 0.45f}), PeakLabel::kPositive);
  EXPECT_EQ(room.matched, (std::vector<bool>{false, true, false, false}));
  EXPECT_EQ(room.label({1.95f, 0.03f, 0.45f}), PeakLabel::kNegative) << "recognition would answer the chair twice";
}

TEST(CalibrationRoom, BackgroundFurnitureStandsAmongTheClutter) {
  const Mesh chair = testing::boxMesh({-0.25f, -0.25f, 0}, {0.25f, 0.25f, 0.9f});
  const Mesh bed = testing::boxMesh({-0.95f, -0.7f, 0}, {0.95f, 0.7f, 0.5f});
  const PlacedObject furniture{"chair", 0, &chair}, background{"background", 0, &bed};
  CalibrationParams params;
  NoiseParams noise;
  int with_bed = 0;
  for (uint32_t seed = 1; seed <= 12; ++seed) {
    std::mt19937 rng(seed);
    const CalibrationRoom room = composeCalibrationRoom({&furniture}, {&background}, params, noise, rng);
    ASSERT_GE(room.categories.size(), 1u);
    EXPECT_EQ(room.categories[0], "chair");
    with_bed += holdsBed(room) ? 1 : 0;
  }
  EXPECT_GE(with_bed, 4) << "up to 2 background objects per room, seen in at least a third of the rooms";
  params.background_objects = 0;
  for (uint32_t seed = 1; seed <= 12; ++seed) {
    std::mt19937 rng(seed);
    EXPECT_FALSE(holdsBed(composeCalibrationRoom({&furniture}, {&background}, params, noise, rng))) << seed;
  }
}

TEST(CalibrationRoom, GroupedRoomsPullTheOtherFurnitureUpToATable) {
  const Mesh table_mesh = testing::boxMesh({-0.6f, -0.4f, 0}, {0.6f, 0.4f, 0.75f});
  const Mesh chair_mesh = testing::boxMesh({-0.25f, -0.25f, 0}, {0.25f, 0.25f, 0.9f});
  const PlacedObject table{"table", 0, &table_mesh}, chair{"chair", 0, &chair_mesh};
  CalibrationParams params;
  params.grouped_rooms = 1;
  NoiseParams noise;
  int chairs = 0, most = 0;
  for (uint32_t seed = 1; seed <= 12; ++seed) {
    std::mt19937 rng(seed);
    const CalibrationRoom room = composeCalibrationRoom({&table, &chair}, {}, params, noise, rng, {&table});
    ASSERT_GE(room.categories.size(), 2u) << seed;
    ASSERT_LE(room.categories.size(), 1u + static_cast<size_t>(params.max_grouped)) << seed;
    ASSERT_EQ(room.categories[0], "table") << seed;
    const GroundTruthObject& top = room.scene.objects[0];
    const Eigen::Rotation2Df to_table(-top.yaw);
    for (size_t i = 1; i < room.categories.size(); ++i) {
      ASSERT_EQ(room.categories[i], "chair") << seed;
      // The chair's centre from the table's edge (half under it) to half its depth out, beside one side.
      const Eigen::Vector2f local = to_table * (room.scene.objects[i].center - top.center).head<2>();
      const float x = std::abs(local.x()), y = std::abs(local.y());
      const bool beside_x = x >= 0.6f - 1e-3f && x <= 0.85f + 1e-3f && y <= 0.4f + 1e-3f;
      const bool beside_y = y >= 0.4f - 1e-3f && y <= 0.65f + 1e-3f && x <= 0.6f + 1e-3f;
      EXPECT_TRUE(beside_x || beside_y) << seed << ": chair at " << local.transpose() << " in the table's frame";
      for (size_t j = 1; j < i; ++j) {
        EXPECT_GT((room.scene.objects[j].center - room.scene.objects[i].center).head<2>().norm(), 0.5f) << seed;
      }
    }
    chairs += static_cast<int>(room.categories.size()) - 1;
    most = std::max(most, static_cast<int>(room.categories.size()) - 1);
  }
  EXPECT_GE(most, 3) << "up to 4 chairs at a table";
  EXPECT_GE(chairs, 18);
  // Without groups the rooms are those composed without tables: the same draws.
  params.grouped_rooms = 0;
  for (uint32_t seed = 1; seed <= 4; ++seed) {
    std::mt19937 a(seed), b(seed);
    const CalibrationRoom with = composeCalibrationRoom({&table, &chair}, {}, params, noise, a, {&table});
    const CalibrationRoom without = composeCalibrationRoom({&table, &chair}, {}, params, noise, b);
    ASSERT_EQ(with.categories, without.categories);
    ASSERT_EQ(with.scene.objects.size(), without.scene.objects.size());
    for (size_t i = 0; i < with.scene.objects.size(); ++i) {
      EXPECT_EQ(with.scene.objects[i].center, without.scene.objects[i].center) << seed;
    }
  }
}

}  // namespace
}  // namespace ism

namespace ism {
namespace {

TEST(CalibrationMap, TheRoomAsARoomScanIsSent) {
  const Mesh chair_mesh = testing::boxMesh({-0.25f, -0.25f, 0}, {0.25f, 0.25f, 0.9f});
  const PlacedObject chair{"chair", 0, &chair_mesh};
  CalibrationParams params;
  params.maps = true;
  NoiseParams noise;
  int maps = 0;
  for (uint32_t seed = 1; seed <= 4; ++seed) {
    std::mt19937 rng(seed);
    const CalibrationRoom room = composeCalibrationRoom({&chair}, {}, params, noise, rng);
    ASSERT_FALSE(room.objects.empty());
    const Scene map = calibrationMap(room, params, rng);
    // Unorganized, without pose, at most map_points_max points, all within the room's walls.
    EXPECT_EQ(map.image_width, 0) << seed;
    EXPECT_EQ(map.sensor_origin, Eigen::Vector3f::Zero()) << seed;
    ASSERT_GE(map.cloud->size(), 1000u) << seed;
    EXPECT_LE(map.cloud->size(), static_cast<size_t>(params.map_points_max)) << seed;
    int on_chair = 0;
    const Eigen::Vector2f chair_at = room.scene.objects[0].center.head<2>();
    for (const auto& p : map.cloud->points) {
      EXPECT_LE(std::abs(p.x), 3.5f + 1e-3f);
      EXPECT_LE(p.y, 2.3f + 1e-3f);
      if ((p.getVector3fMap().head<2>() - chair_at).norm() < 0.3f && p.z > 0.1f && p.z < 0.95f) ++on_chair;
    }
    EXPECT_GT(on_chair, 50) << seed << ": the chair is in the map";
    // Recognition takes it for a map: its points all around the viewpoint it makes up.
    maps += isMap(lookedAt(map)) ? 1 : 0;
  }
  // One view can leave too few points behind that viewpoint; the calibration skips such a map.
  EXPECT_GE(maps, 3);
}

TEST(FitCalibration, TheProfileDecidesWhereScoreAndFitCannot) {
  // Scores and fits drawn alike for both; positives' surface is shaped like the training shapes
  // (profile distance 0.1-0.5), negatives' is not (0.6-1.4).
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> score(0.05f, 2.0f), fit(0.3f, 0.9f), near(0.1f, 0.5f), far(0.6f, 1.4f);
  std::vector<CalibrationSample> samples;
  for (int i = 0; i < 400; ++i) {
    CalibrationSample& s = samples.emplace_back();
    s.positive = i % 4 == 0;
    s.score = score(rng);
    s.support = 10;
    s.fit = fit(rng);
    s.profile_distance = s.positive ? near(rng) : far(rng);
  }
  const Calibration with = fitCalibration(samples);
  EXPECT_LT(with.e, -5.0f);
  EXPECT_GT(with.confidence(0.5f, 10, 0.6f, 0.2f), 0.9f);
  EXPECT_LT(with.confidence(0.5f, 10, 0.6f, 1.0f), 0.1f);
  const Calibration without = fitCalibration(samples, false);
  EXPECT_EQ(without.e, 0.0f);
  EXPECT_NEAR(without.confidence(0.5f, 10, 0.6f, 0.2f), without.confidence(0.5f, 10, 0.6f, 1.0f), 1e-6f);
}

// Samples of one category whose fit decides (positives 0.6-1.0, negatives 0.1-0.7) and whose
// score says nothing, spread over three folds of rooms.
std::vector<CalibrationSample> fitDecides(int category, int count, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> score(0.05f, 2.0f), good(0.6f, 1.0f), bad(0.1f, 0.7f);
  std::vector<CalibrationSample> samples;
  for (int i = 0; i < count; ++i) {
    CalibrationSample& s = samples.emplace_back();
    s.category = category;
    s.positive = i % 5 == 0;
    s.score = score(rng);
    s.support = 10;
    s.fit = s.positive ? good(rng) : bad(rng);
    s.fold = i % 3;
  }
  return samples;
}

TEST(FitCalibrations, AloneTheyAreEachCategorysOwnFit) {
  const std::vector<std::vector<CalibrationSample>> groups = {fitDecides(0, 300, 1), fitDecides(1, 200, 2)};
  double chosen = -1;
  const auto fits = fitCalibrations(groups, {true, true}, {}, &chosen);
  EXPECT_EQ(chosen, 0.0);
  ASSERT_EQ(fits.size(), 2u);
  for (size_t g = 0; g < 2; ++g) {
    ASSERT_TRUE(fits[g]);
    const Calibration alone = fitCalibration(groups[g]);
    EXPECT_FLOAT_EQ(fits[g]->d, alone.d);
    EXPECT_FLOAT_EQ(fits[g]->b, alone.b);
  }
}

TEST(FitCalibrations, AFewPeaksBorrowTheOtherCategoriesSlopes) {
  // Two categories where the fit decides, and a third with 4 positives among 40 whose score
  // happens to separate them and whose fit, by chance, does not.
  std::vector<std::vector<CalibrationSample>> groups = {fitDecides(0, 600, 3), fitDecides(1, 600, 4)};
  std::vector<CalibrationSample>& few = groups.emplace_back();
  for (int i = 0; i < 40; ++i) {
    CalibrationSample& s = few.emplace_back();
    s.category = 2;
    s.positive = i % 10 == 0;
    s.score = s.positive ? 1.5f + 0.01f * static_cast<float>(i) : 0.2f + 0.02f * static_cast<float>(i);
    s.support = 10;
    s.fit = 0.3f + 0.01f * static_cast<float>(i % 7);
    s.fold = i % 3;
  }
  const Calibration alone = fitCalibration(few);
  const auto pooled = fitCalibrations(groups, {true, true, true}, {0.25});
  ASSERT_TRUE(pooled[2]);
  // Alone, the few peaks' fit weighs next to nothing; drawn towards the others', it weighs much.
  EXPECT_LT(std::abs(alone.d), 2.0f);
  EXPECT_GT(pooled[2]->d, alone.d + 3.0f);
  EXPECT_EQ(pooled[2]->positives, 4);
  EXPECT_EQ(pooled[2]->negatives, 36);
}

TEST(FitCalibrations, TheSpreadIsChosenOnHeldOutFoldsAndAGroupWithoutPositivesGetsNone) {
  std::vector<std::vector<CalibrationSample>> groups = {fitDecides(0, 300, 5), fitDecides(1, 300, 6), {}};
  for (int i = 0; i < 30; ++i) groups[2].push_back({2, 0.1f * static_cast<float>(i + 1), 5, false, 0.5f});
  double chosen = -1;
  const std::vector<double> spreads = {0.0, 0.5, 2.0};
  const auto fits = fitCalibrations(groups, {true, true, true}, spreads, &chosen);
  EXPECT_NE(std::find(spreads.begin(), spreads.end(), chosen), spreads.end());
  ASSERT_EQ(fits.size(), 3u);
  EXPECT_TRUE(fits[0]);
  EXPECT_TRUE(fits[1]);
  EXPECT_FALSE(fits[2]);
  // The two categories are alike: every spread predicts the held-out folds alike, so whichever was
  // chosen, the fit decides.
  EXPECT_GT(fits[0]->confidence(1.0f, 10, 0.95f), 0.5f);
  EXPECT_LT(fits[0]->confidence(1.0f, 10, 0.2f), 0.05f);
}

}  // namespace
}  // namespace ism
