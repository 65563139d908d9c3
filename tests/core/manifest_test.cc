#include "core/training/manifest.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/common/error.h"
#include "core/training/trainer.h"

namespace ism {
namespace {

namespace fs = std::filesystem;

class TrainingFiles : public ::testing::Test {
 protected:
  fs::path dir = fs::path(::testing::TempDir()) /
                 ("manifest_test_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
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
  EXPECT_FALSE(meshes[0].placement.size_guessed);
  EXPECT_EQ(meshes[1].path, "/abs/chair.off");
  EXPECT_EQ(meshes[1].placement.up, UpAxis::kY);
  EXPECT_TRUE(meshes[1].placement.uniform);  // no size given: own proportions, fitted to the typical size
  EXPECT_TRUE(meshes[1].placement.size.isApprox(defaultCategorySize("dining_chair")));
  EXPECT_TRUE(meshes[1].placement.size_guessed);
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
  EXPECT_TRUE(meshes[2].placement.size_guessed);
  write("spaceship/s.obj", "");
  EXPECT_THROW(meshesFromFolders(dir.string()), Error);  // no size known for it
}

TEST_F(TrainingFiles, UnsizedMeshesFitTheTypicalBoxOrTheSeedsHeight) {
  // A Y-up box 6 wide, 1 high, 1 deep, listed as a couch without a size.
  std::string obj;
  for (float x : {-3.0f, 3.0f}) {
    for (float y : {0.0f, 1.0f}) {
      for (float z : {-0.5f, 0.5f}) obj += "v " + std::to_string(x) + " " + std::to_string(y) + " " + std::to_string(z) + "\n";
    }
  }
  obj += "f 1 2 4\nf 1 4 3\nf 5 7 8\nf 5 8 6\nf 1 5 6\nf 1 6 2\nf 3 4 8\nf 3 8 7\nf 1 3 7\nf 1 7 5\nf 2 6 8\nf 2 8 4\n";
  write("couch/long.obj", obj);
  const auto meshes = meshesFromFolders(dir.string());
  ASSERT_EQ(meshes.size(), 1u);
  const Eigen::Vector3f typical = defaultCategorySize("couch");  // 2.0 x 0.9 x 0.85

  // The default: one factor, the geometric mean of 2.0 / 6, 0.9 / 1 and 0.85 / 1.
  TrainingParams params;
  params.threads = 1;
  const float fit = std::cbrt(typical.x() / 6 * typical.y() * typical.z());
  EXPECT_TRUE(placeMeshes(meshes, params)[0].bounds().sizes().isApprox(Eigen::Vector3f(6, 1, 1) * fit, 1e-4f));

  // The seed's preset: the height alone, so the couch comes out 5.1 m long.
  params.unsized_by_height = seedTrainingParams().unsized_by_height;
  EXPECT_TRUE(placeMeshes(meshes, params)[0].bounds().sizes().isApprox(Eigen::Vector3f(6, 1, 1) * typical.z(), 1e-4f));
}

}  // namespace
}  // namespace ism
