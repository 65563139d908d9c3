#include "core/training/trainer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "core/common/error.h"
#include "core/model/model_file.h"
#include "tests/common/hand_made_scans.h"
#include "tests/common/synthetic_furniture.h"

namespace ism {
namespace {

using namespace ism::testing;

// The hand-made scans have LRFs but no up: their votes are the seed's.
TrainingParams smallParams() {
  TrainingParams p = seedTrainingParams();
  p.global_kmeans.k = 2 * kKeypoints;
  p.separated_kmeans.k = kKeypoints;
  return p;
}

TEST(TrainFromScans, LeaveOneOutThresholdsHaveTheKnownValues) {
  std::vector<TrainingScan> scans = handMadeScans("stool", 1);
  const auto more = handMadeScans("bed", 2);
  scans.insert(scans.end(), more.begin(), more.end());
  TrainingParams params = smallParams();
  params.bin_sizes["bed"] = 0.2f;
  std::vector<std::string> lines;
  params.progress = [&](const std::string& line) { lines.push_back(line); };
  const Model model = trainFromScans(scans, {"stool", "bed"}, params);

  ASSERT_TRUE(model.has(CodebookType::kGlobal));
  ASSERT_TRUE(model.has(CodebookType::kSeparated));
  EXPECT_EQ(model.global_codebook->size(), 2 * kKeypoints);
  EXPECT_FALSE(lines.empty());
  ASSERT_EQ(model.categories.size(), 2u);
  EXPECT_EQ(model.categories[0].bin_size, params.default_bin_size);
  EXPECT_EQ(model.categories[1].bin_size, 0.2f);
  for (const auto& c : model.categories) {
    SCOPED_TRACE(c.name);
    EXPECT_EQ(c.training_models, kModels);
    EXPECT_EQ(c.training_scans, kModels * kScansPerModel);
    // 1-NN during training: exactly one vote per training keypoint.
    EXPECT_EQ(c.global_votes.vectors.size(), static_cast<size_t>(kModels * kScansPerModel * kKeypoints));
    EXPECT_EQ(c.own_votes.vectors.size(), static_cast<size_t>(kModels * kScansPerModel * kKeypoints));
    ASSERT_EQ(c.thresholds.size(), 12u);
    for (CodebookType type : {CodebookType::kGlobal, CodebookType::kSeparated}) {
      for (ActivationStrategy a : {ActivationStrategy::kKnn, ActivationStrategy::kCutoff}) {
        const float cw = c.thresholds.at({type, a, VoteWeighting::kCategorization});
        const float lw = c.thresholds.at({type, a, VoteWeighting::kLocalization});
        const float aw = c.thresholds.at({type, a, VoteWeighting::kActivation});
        EXPECT_NEAR(cw, kKeypoints * (kModels - 1) * kScansPerModel, 1e-3f);
        EXPECT_NEAR(lw, kKeypoints, 1e-3f);
        EXPECT_LT(aw, lw);
        EXPECT_GT(aw, 0.99f * lw);  // descriptors lie ~1e-3 from their codeword
      }
    }
    // Every scan has the same keypoint geometry, so the box statistics have no spread.
    EXPECT_NEAR(c.box.std_volume, 0.0f, 1e-5f);
    EXPECT_NEAR(c.box.min_volume, c.box.mean_volume, 1e-5f);
    EXPECT_NEAR(c.box.max_volume, c.box.mean_volume, 1e-5f);
    EXPECT_NEAR(c.box.max_edge, scans[&c == &model.categories[0] ? 0 : scans.size() - 1].keypoint_box.longestEdge(), 1e-4f);
  }
}

// Held out, models 0 and 1 get the votes of the other's 4 scans at their centre, model 2 none:
// CW scores 48, 48, 0 per scan (4 scans each), mean 32, std sqrt(512) = 22.6. The seed's
// mean - std = 9.4 is below half the mean, so the threshold is floored to 16.
TEST(TrainFromScans, ThresholdsOfDissimilarModelsAreFlooredAndTheStatisticsKept) {
  TrainingParams params = smallParams();
  params.separated_codebooks = false;
  params.global_kmeans.k = kKeypoints;  // one category: one codeword per prototype
  std::vector<std::string> lines;
  params.progress = [&](const std::string& line) { lines.push_back(line); };
  const Model model = trainFromScans(handMadeScans("stool", 3, 2), {"stool"}, params);
  const ThresholdKey cw{CodebookType::kGlobal, ActivationStrategy::kKnn, VoteWeighting::kCategorization};
  const CategoryModel& c = model.categories.at(0);
  const float mean = 2.0f / 3 * kKeypoints * kScansPerModel, std = std::sqrt(512.0f);
  EXPECT_NEAR(c.threshold_stats.at(cw).mean, mean, 1e-3f);
  EXPECT_NEAR(c.threshold_stats.at(cw).std, std, 1e-3f);
  EXPECT_NEAR(c.thresholds.at(cw), 0.5f * mean, 1e-3f);
  ASSERT_EQ(c.threshold_stats.size(), c.thresholds.size());
  for (const auto& [key, threshold] : c.thresholds) {
    const ThresholdStats& stats = c.threshold_stats.at(key);
    EXPECT_FLOAT_EQ(threshold, std::max(stats.mean - stats.std, 0.5f * stats.mean));
    EXPECT_GT(threshold, 0.0f);
  }
  EXPECT_TRUE(std::any_of(lines.begin(), lines.end(), [](const std::string& l) {
    return l.find("knn/cw=16.000(floored; mean 32.000 - std 22.627)") != std::string::npos;
  })) << "no progress line names the floored threshold";

  // The statistics survive the model file.
  const Model reloaded = parseModel(serializeModel(model), "memory");
  EXPECT_EQ(reloaded.categories.at(0).thresholds, c.thresholds);
  EXPECT_EQ(reloaded.categories.at(0).threshold_stats.at(cw).mean, c.threshold_stats.at(cw).mean);
  EXPECT_EQ(reloaded.categories.at(0).threshold_stats.at(cw).std, c.threshold_stats.at(cw).std);

  // A floor of 0 is the seed's rule unchanged; outside [0, 1] is refused.
  params.threshold_floor = 0;
  EXPECT_NEAR(trainFromScans(handMadeScans("stool", 3, 2), {"stool"}, params).categories[0].thresholds.at(cw),
              mean - std, 1e-3f);
  params.threshold_floor = 1.5f;
  EXPECT_THROW(trainFromScans(handMadeScans("stool", 3, 2), {"stool"}, params), Error);
}

// A stool's scans beside ten times as many bed scans: pooled, the global codebook's k-means
// gets every descriptor (and samples max_samples of them, 1 in 11 a stool's); balanced, as many of
// each category's, half of max_samples each.
TEST(TrainFromScans, ABalancedCodebookClustersAsManyDescriptorsOfEachCategory) {
  std::vector<TrainingScan> scans = handMadeScans("stool", 1);
  for (uint32_t copy = 0; copy < 10; ++copy) {
    const auto beds = handMadeScans("bed", 2 + copy);
    scans.insert(scans.end(), beds.begin(), beds.end());
  }
  TrainingParams params = smallParams();
  params.separated_codebooks = false;
  params.global_kmeans.max_samples = 4 * kKeypoints;
  const auto codebookLine = [&](bool balanced) {
    params.balanced_global_codebook = balanced;
    std::string line;
    params.progress = [&](const std::string& l) {
      if (l.find("codebook: k-means") != std::string::npos) line = l;
    };
    trainFromScans(scans, {"stool", "bed"}, params);
    return line;
  };
  const int all = static_cast<int>(scans.size()) * kKeypoints;
  EXPECT_EQ(codebookLine(false).rfind("global codebook: k-means of " + std::to_string(all) + " descriptors", 0), 0u);
  EXPECT_EQ(codebookLine(true).rfind("global (balanced) codebook: k-means of " + std::to_string(4 * kKeypoints) + " descriptors", 0),
            0u);
}

// The footprint prior (top_extent.h) looks only at objects whose size was given.
TEST(TrainFromScans, ObjectsKeepWhetherTheirSizeWasAGuess) {
  std::vector<TrainingScan> scans = handMadeScans("stool", 1);
  const auto more = handMadeScans("bed", 2);
  scans.insert(scans.end(), more.begin(), more.end());
  for (auto& s : scans) {
    s.object_size = {0.4f, 0.4f, 0.6f};
    s.size_guessed = s.category == "bed";
  }
  const Model model = trainFromScans(scans, {"stool", "bed"}, smallParams());
  ASSERT_EQ(model.categories.size(), 2u);
  for (const auto& c : model.categories) {
    ASSERT_EQ(c.objects.size(), static_cast<size_t>(kModels)) << c.name;
    for (const auto& o : c.objects) EXPECT_EQ(o.size_guessed, c.name == "bed") << c.name;
  }
}

TEST(TrainFromScans, NeedsTwoModelsPerCategory) {
  std::vector<TrainingScan> scans = handMadeScans("stool", 1);
  for (auto& s : scans) s.model_index = 0;
  EXPECT_THROW(trainFromScans(scans, {"stool"}, smallParams()), Error);
  EXPECT_THROW(trainFromScans(handMadeScans("stool", 1), {"desk"}, smallParams()), Error);
}

// A mesh's views fused into one map (TrainingParams::fused) hold its surface all around, without
// an image grid, as a mapping stack's cloud does; a single view sees one side.
TEST(ScanMeshes, AFusedScanSurroundsTheObject) {
  TrainingParams params;
  params.views.views = 4;
  params.threads = 2;
  params.fused.enabled = true;
  TrainingMesh mesh;
  mesh.category = "office_chair";
  mesh.path = "procedural office chair";
  mesh.placement.size_guessed = true;
  const std::vector<Mesh> placed{syntheticFurniture("office_chair", 0)};
  const std::vector<TrainingScan> scans = scanMeshes({mesh}, placed, params);
  ASSERT_EQ(scans.size(), 5u) << "4 views, then the fused scan";
  for (const auto& s : scans) EXPECT_TRUE(s.size_guessed) << "each scan says its mesh's size was a guess";
  const TrainingScan& fused = scans.back();
  EXPECT_FALSE(fused.features.organized);
  EXPECT_EQ(fused.model_index, 0);
  EXPECT_EQ(fused.object_center, scans.front().object_center);
  for (int v = 0; v < 4; ++v) EXPECT_TRUE(scans[static_cast<size_t>(v)].features.organized) << "view " << v;
  ASSERT_GT(fused.features.size(), 20u);
  int quadrant[4] = {0, 0, 0, 0};
  Eigen::AlignedBox3f reach;
  for (const auto& p : fused.features.positions) {
    ++quadrant[(p.x() > fused.object_center.x() ? 1 : 0) + (p.y() > fused.object_center.y() ? 2 : 0)];
    reach.extend(p);
  }
  for (int q = 0; q < 4; ++q) EXPECT_GT(quadrant[q], 0) << "keypoints on every side, quadrant " << q;
  const Eigen::AlignedBox3f object = placed.front().bounds();
  for (int axis = 0; axis < 2; ++axis) {
    EXPECT_LT(reach.min()[axis], object.min()[axis] + 0.1f) << "axis " << axis;
    EXPECT_GT(reach.max()[axis], object.max()[axis] - 0.1f) << "axis " << axis;
  }

  params.fused.enabled = false;
  EXPECT_EQ(scanMeshes({mesh}, placed, params).size(), 4u);
}

TEST(TrainingDefaults, BinSizesFollowTheSeed) {
  EXPECT_EQ(defaultBinSize("dining_chair"), 0.1f);
  EXPECT_EQ(defaultBinSize("office_chair"), 0.1f);
  EXPECT_EQ(defaultBinSize("dining_table"), 0.2f);
  EXPECT_EQ(defaultBinSize("couch"), 0.2f);
  EXPECT_THROW(defaultCategorySize("spaceship"), Error);
}

}  // namespace
}  // namespace ism
