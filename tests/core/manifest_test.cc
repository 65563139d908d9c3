#include "core/training/manifest.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/common/error.h"

namespace ism {
namespace {

namespace fs = std::filesystem;

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

}  // namespace
}  // namespace ism
