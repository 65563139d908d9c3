#include "core/training/trainer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/common/error.h"
#include "core/model/model_file.h"
#include "core/recognition/recognizer.h"

namespace ism {
namespace {

namespace fs = std::filesystem;

constexpr int kKeypoints = 12;  // per scan, one per descriptor prototype
constexpr int kModels = 3;
constexpr int kScansPerModel = 4;

// Hand-made scans with exactly known leave-one-out answers: keypoint j of every scan of a
// category has the same descriptor prototype and the same pose relative to the object, only
// the whole object moves and turns between scans. Then codeword j holds identical votes, and a
// held-out scan's keypoint j gets (kModels - 1) * kScansPerModel CW votes, all at its centre.
// Model `odd_model` (if any) has the same descriptors but another keypoint geometry, as a
// dissimilar training model would: its votes miss the other models' centres and theirs miss its.
std::vector<TrainingScan> handMadeScans(const std::string& category, uint32_t seed, int odd_model = -1) {
  std::srand(seed);
  DescriptorMatrix prototypes = DescriptorMatrix::Random(kKeypoints, 16);
  prototypes.rowwise().normalize();
  std::vector<Eigen::Vector3f> offsets, odd_offsets;
  std::vector<Eigen::Matrix3f> lrfs;
  for (int j = 0; j < kKeypoints; ++j) {
    offsets.push_back(0.3f * Eigen::Vector3f::Random());
    odd_offsets.push_back(offsets.back() + Eigen::Vector3f(0.5f, 0, 0));
    lrfs.push_back(Eigen::Quaternionf::UnitRandom().toRotationMatrix());
  }
  std::vector<TrainingScan> scans;
  for (int m = 0; m < kModels; ++m) {
    for (int s = 0; s < kScansPerModel; ++s) {
      TrainingScan scan;
      scan.category = category;
      scan.model_index = m;
      scan.object_center = 2.0f * Eigen::Vector3f::Random();
      const Eigen::Matrix3f turn = Eigen::AngleAxisf(0.4f * s + m, Eigen::Vector3f::UnitZ()).toRotationMatrix();
      scan.features.descriptors = prototypes + 1e-3f * DescriptorMatrix::Random(kKeypoints, 16);
      for (int j = 0; j < kKeypoints; ++j) {
        const auto& offset = (m == odd_model ? odd_offsets : offsets)[static_cast<size_t>(j)];
        scan.features.positions.push_back(scan.object_center + turn * offset);
        scan.features.lrfs.push_back(lrfs[static_cast<size_t>(j)] * turn.transpose());
      }
      scan.keypoint_box = fitOrientedBox(scan.features.positions);
      scans.push_back(std::move(scan));
    }
  }
  return scans;
}

TrainingParams smallParams() {
  TrainingParams p;
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

TEST(TrainFromScans, NeedsTwoModelsPerCategory) {
  std::vector<TrainingScan> scans = handMadeScans("stool", 1);
  for (auto& s : scans) s.model_index = 0;
  EXPECT_THROW(trainFromScans(scans, {"stool"}, smallParams()), Error);
  EXPECT_THROW(trainFromScans(handMadeScans("stool", 1), {"desk"}, smallParams()), Error);
}

class TrainingFiles : public ::testing::Test {
 protected:
  fs::path dir = fs::path(::testing::TempDir()) /
                 ("training_test_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
  void SetUp() override { fs::create_directories(dir); }
  void TearDown() override { fs::remove_all(dir); }
  std::string write(const std::string& name, const std::string& text) {
    fs::create_directories((dir / name).parent_path());
    std::ofstream(dir / name) << text;
    return (dir / name).string();
  }
};

TEST_F(TrainingFiles, ReadsAManifest) {
  const std::string path = write("m.tsv",
                                 "category\tpath\twidth_m\tdepth_m\theight_m\tup\trotation\tcredit\n"
                                 "couch\tsofa.obj\t2.0\t0.9\t0.8\tz\t-1 0 0 0 1 0 0 0 -1\tsomeone, CC-BY\n"
                                 "# a comment\n"
                                 "dining_chair\t/abs/chair.off\n");
  const auto meshes = readManifest(path);
  ASSERT_EQ(meshes.size(), 2u);
  EXPECT_EQ(meshes[0].category, "couch");
  EXPECT_EQ(meshes[0].path, (dir / "sofa.obj").string());
  EXPECT_TRUE(meshes[0].placement.size.isApprox(Eigen::Vector3f(2.0f, 0.9f, 0.8f)));
  EXPECT_EQ(meshes[0].placement.up, UpAxis::kZ);
  EXPECT_EQ(meshes[0].placement.pre_rotation(0, 0), -1.0f);
  EXPECT_EQ(meshes[0].credit, "someone, CC-BY");
  EXPECT_EQ(meshes[1].path, "/abs/chair.off");
  EXPECT_EQ(meshes[1].placement.up, UpAxis::kY);
  EXPECT_TRUE(meshes[1].placement.uniform);  // no size given: typical height, own proportions
  EXPECT_EQ(meshes[1].placement.size.z(), defaultCategorySize("dining_chair").z());
}

TEST_F(TrainingFiles, ManifestErrorsNameTheLine) {
  const std::string path = write("bad.tsv", "category\tpath\theight_m\ncouch\ta.obj\t0.8\ncouch\tb.obj\ttall\n");
  try {
    readManifest(path);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidInput);
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'tall'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(readManifest(write("nocat.tsv", "path\nx.obj\n")), Error);
  EXPECT_THROW(readManifest((dir / "absent.tsv").string()), Error);
}

TEST_F(TrainingFiles, FindsMeshesInCategoryFolders) {
  write("couch/b.obj", "");
  write("couch/a.OFF", "");
  write("couch/notes.txt", "");
  write("dining_table/t.ply", "");
  const auto meshes = meshesFromFolders(dir.string());
  ASSERT_EQ(meshes.size(), 3u);
  EXPECT_EQ(meshes[0].category, "couch");
  EXPECT_EQ(fs::path(meshes[0].path).filename(), "a.OFF");
  EXPECT_EQ(meshes[2].category, "dining_table");
  EXPECT_EQ(meshes[2].placement.size.z(), defaultCategorySize("dining_table").z());
  write("spaceship/s.obj", "");
  EXPECT_THROW(meshesFromFolders(dir.string()), Error);  // no size known for it
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
