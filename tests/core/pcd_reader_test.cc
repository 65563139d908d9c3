// core/io/pcd_reader: what PCL writes reads back exactly, and a header that lies about its body
// is refused with a message before anything is allocated for it.
#include "core/io/pcd_reader.h"

#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include "core/common/error.h"
#include "core/io/cloud_io.h"
#include "core/io/file_bytes.h"
#include "tests/common/expect_error.h"

namespace ism {
namespace {

namespace fs = std::filesystem;
using ism::testing::expectError;

// A 4x3 organized cloud with colour, two missing pixels and a sensor pose, as PCL writes it.
pcl::PointCloud<pcl::PointXYZRGB> organizedCloud() {
  pcl::PointCloud<pcl::PointXYZRGB> cloud(4, 3);
  for (int i = 0; i < 12; ++i) {
    auto& p = cloud[i];
    p.x = 0.1f * (i % 4) - 0.15f;
    p.y = 0.1f * (i / 4) - 0.1f;
    p.z = 1.0f + 0.01f * i;
    p.r = static_cast<uint8_t>(20 * i);
    p.g = static_cast<uint8_t>(255 - 20 * i);
    p.b = 7;
  }
  cloud[5].x = cloud[5].y = cloud[5].z = std::numeric_limits<float>::quiet_NaN();
  cloud[10].z = std::numeric_limits<float>::quiet_NaN();
  cloud.is_dense = false;
  cloud.sensor_origin_ = Eigen::Vector4f(0.5f, -1.0f, 1.25f, 0.0f);
  cloud.sensor_orientation_ = Eigen::Quaternionf(Eigen::AngleAxisf(0.3f, Eigen::Vector3f::UnitZ()));
  return cloud;
}

class PcdReaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("ism_pcd_reader_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(PcdReaderTest, ReadsWhatPclWritesInEveryEncoding) {
  const auto cloud = organizedCloud();
  const std::string ascii = path("ascii.pcd"), binary = path("binary.pcd"), compressed = path("compressed.pcd");
  ASSERT_EQ(pcl::io::savePCDFileASCII(ascii, cloud), 0);
  ASSERT_EQ(pcl::io::savePCDFileBinary(binary, cloud), 0);
  ASSERT_EQ(pcl::io::savePCDFileBinaryCompressed(compressed, cloud), 0);
  for (const auto& file : {ascii, binary, compressed}) {
    SCOPED_TRACE(file);
    const Scene scene = loadCloudFile(file);
    EXPECT_EQ(scene.image_width, 4);
    EXPECT_EQ(scene.image_height, 3);
    EXPECT_TRUE(scene.has_color);
    ASSERT_EQ(scene.cloud->size(), 10u);
    ASSERT_EQ(scene.pixel_index.size(), 10u);
    for (size_t k = 0; k < scene.cloud->size(); ++k) {
      const auto& got = scene.cloud->at(k);
      const auto& want = cloud[scene.pixel_index[k]];
      EXPECT_NE(scene.pixel_index[k], 5);
      EXPECT_NE(scene.pixel_index[k], 10);
      // ASCII keeps PCL's default 8 significant digits.
      EXPECT_NEAR(got.x, want.x, 1e-6f);
      EXPECT_NEAR(got.y, want.y, 1e-6f);
      EXPECT_NEAR(got.z, want.z, 1e-6f);
      EXPECT_EQ(got.r, want.r);
      EXPECT_EQ(got.g, want.g);
      EXPECT_EQ(got.b, want.b);
    }
    EXPECT_TRUE(scene.sensor_origin.isApprox(cloud.sensor_origin_.head<3>()));
    EXPECT_TRUE(scene.sensor_orientation.isApprox(cloud.sensor_orientation_, 1e-5f));
  }
}

// Older and hand-written files: v0.5 (POINTS only, no WIDTH or COUNT), float64 coordinates, a
// padding field, colour written as the float whose bits it is, comments and CRLF line ends.
TEST_F(PcdReaderTest, ReadsOlderAndHandWrittenHeaders) {
  float packed;
  const uint32_t rgb = 0x00FF8000u;
  std::memcpy(&packed, &rgb, sizeof packed);
  char rgb_as_float[64];
  std::snprintf(rgb_as_float, sizeof rgb_as_float, "%.9g", packed);
  const std::string text = std::string("# written by hand\r\nVERSION .5\r\nFIELDS x y _ z rgb\r\nSIZE 8 8 1 4 4\r\n") +
                           "TYPE F F U F F\r\nPOINTS 2\r\nDATA ascii\r\n1.5 -2 9 +3e-1 " + rgb_as_float +
                           "\r\n\r\n  0 0 0 nan 0\r\n";
  const PcdCloud pcd = parsePcd(text, "hand.pcd");
  EXPECT_EQ(pcd.blob.width, 2u);
  EXPECT_EQ(pcd.blob.height, 1u);
  EXPECT_EQ(pcd.blob.point_step, 8u + 8u + 1u + 4u + 4u);
  writeFileBytes(path("hand.pcd"), text);
  const Scene scene = loadCloudFile(path("hand.pcd"));
  ASSERT_EQ(scene.cloud->size(), 1u);  // the NaN point is dropped
  EXPECT_EQ(scene.cloud->at(0).getVector3fMap(), Eigen::Vector3f(1.5f, -2.0f, 0.3f));
  EXPECT_EQ(scene.cloud->at(0).r, 0xFF);
  EXPECT_EQ(scene.cloud->at(0).g, 0x80);
  EXPECT_EQ(scene.cloud->at(0).b, 0x00);
  EXPECT_TRUE(scene.pixel_index.empty());
}

const std::string kXyz = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n";

// Each header lies about its body in a way that made PCL's reader overrun, crash or allocate
// gigabytes (tests/fuzz/corpus/pcd/crash_* and oom_*); each is now refused, naming the problem.
TEST_F(PcdReaderTest, RefusesHeadersThatDoNotFitTheirBody) {
  const auto refuses = [](const std::string& text, const std::string& message) {
    SCOPED_TRACE(message);
    expectError([&] { parsePcd(text, "x.pcd"); }, ErrorCode::kInvalidInput, "x.pcd: malformed PCD file: " + message);
  };
  refuses("", "the header has no DATA line");
  refuses("DATA", "DATA must name one of");
  refuses("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\n", "the header has no DATA line");
  refuses("this is not a point cloud\n", "header line 1 starts with 'this', not a PCD keyword");
  refuses("FIELDS x y z\nSIZE 4 4\nTYPE F F F\nPOINTS 1\nDATA ascii\n1 2 3\n", "SIZE has 2 entries for 3 FIELDS");
  refuses("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1\nPOINTS 1\nDATA ascii\n1 2 3\n",
          "COUNT has 2 entries for 3 FIELDS");
  refuses("FIELDS x y z\nSIZE 8 40 0\nTYPE F F F\nPOINTS 2\nDATA ascii\n", "field 'y' has TYPE 'F' and SIZE '40'");
  refuses("FIELDS x y z\nSIZE 4 4 4\nTYPE F F Q\nPOINTS 2\nDATA ascii\n", "field 'z' has TYPE 'Q'");
  refuses(kXyz + "COUNT 1 0 1\nPOINTS 2\nDATA ascii\n", "field 'y' has COUNT '0'");
  refuses(kXyz + "COUNT 1 1 4000000000\nPOINTS 2\nDATA ascii\n", "field 'z' has COUNT '4000000000'");
  refuses(kXyz + "COUNT 1 1 900000\nPOINTS 2\nDATA ascii\n", "its points are larger than 1 MiB each");
  refuses(kXyz + "WIDTH 3\nHEIGHT 2\nPOINTS 5\nDATA ascii\n", "WIDTH x HEIGHT = 3 x 2 does not match POINTS 5");
  refuses(kXyz + "WIDTH 0 0 0\nPOINTS 6\nDATA binary\n", "WIDTH must be one whole number");
  refuses(kXyz + "POINTS -1\nDATA binary\n", "POINTS must be one whole number below 2^32, the header has '-1'");
  refuses(kXyz + "WIDTH 0\nHEIGHT 1\nPOINTS 0\nDATA binary\n", "the header declares no points");
  refuses(kXyz + "WIDTH 65536\nHEIGHT 65536\nDATA binary\n", "4294967296 points are more than 2^31 - 1");
  refuses(kXyz + "VIEWPOINT 0 0 0 1 0 0\nPOINTS 1\nDATA binary\n", "VIEWPOINT must be 7 finite numbers");
  refuses(kXyz + "VIEWPOINT 0 0 0 0 0 0 0\nPOINTS 1\nDATA ascii\n1 2 3\n", "the VIEWPOINT quaternion");
  refuses(kXyz + "POINTS 1\nDATA lzma\n1 2 3\n", "DATA 'lzma' is not ascii, binary or binary_compressed");
  // 12.9 GB from PCL for a 240-byte file: 4e9 points of 12 bytes, and the body holds 10 bytes.
  refuses(kXyz + "POINTS 2000000000\nDATA binary\n0123456789",
          "the binary body holds 10 bytes, the header's 2000000000 points of 12 bytes need 24000000000");
  refuses(kXyz + "POINTS 2000000000\nDATA ascii\n1 2 3\n", "the ascii body of 6 bytes is too short");
  refuses(kXyz + "POINTS 3\nDATA ascii\n1 2 3\n4 5 6\n      \n", "the ascii body ends after 2 of 3 points");
  refuses(kXyz + "POINTS 2\nDATA ascii\n1 2 3\n4 5 6 7\n", "point 2 has 4 values, the header's fields need 3");
  refuses(kXyz + "POINTS 1\nDATA ascii\n1 2 abc\n", "point 1: 'abc' is not a valid value for field 'z'");
  refuses("FIELDS x y z i\nSIZE 4 4 4 1\nTYPE F F F U\nPOINTS 1\nDATA ascii\n1 2 3 256\n",
          "point 1: '256' is not a valid value for field 'i'");
  refuses(kXyz + "POINTS 6\nDATA binary_compressed\n\x01", "the binary_compressed body is truncated before its sizes");
  // Sizes: compressed, uncompressed.
  const auto compressed = [](uint32_t stored, uint32_t unpacked, const std::string& lzf) {
    std::string text = kXyz + "POINTS 6\nDATA binary_compressed\n";
    const uint32_t sizes[2] = {stored, unpacked};
    return text.append(reinterpret_cast<const char*>(sizes), sizeof sizes).append(lzf);
  };
  refuses(compressed(4, 64, "\x03" "abc"), "the compressed body unpacks to 64 bytes, the header's points need 72");
  refuses(compressed(400, 72, "\x03" "abc"), "the compressed body is 400 bytes long but the file holds 4");
  refuses(compressed(0, 72, ""), "a compressed body of 0 bytes cannot unpack to 72");
  refuses(compressed(4, 72, "\x03" "abc"), "the compressed body is corrupt");
}

// Every seed and past finding of the PCD and PLY fuzzers loads or is refused with ism::Error: the
// fuzzers' contract, checked on every build (they run only under clang with libFuzzer).
TEST(PcdReaderCorpus, EveryFuzzSeedLoadsOrIsRefused) {
  const fs::path corpus = fs::path(ISM_SOURCE_DIR) / "tests" / "fuzz" / "corpus";
  int files = 0, loaded = 0;
  const fs::path scratch = fs::temp_directory_path() / ("ism_pcd_corpus_" + std::to_string(::getpid()));
  fs::create_directories(scratch);
  for (const char* format : {"pcd", "ply"}) {
    for (const auto& entry : fs::directory_iterator(corpus / format)) {
      SCOPED_TRACE(entry.path().string());
      // The loaders choose by extension; findings are saved without one.
      const std::string copy = (scratch / (entry.path().stem().string() + "." + format)).string();
      fs::copy_file(entry.path(), copy, fs::copy_options::overwrite_existing);
      ++files;
      try {
        const Scene scene = loadCloudFile(copy);
        ++loaded;
        for (const auto& p : scene.cloud->points) ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
      } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::kInvalidInput) << e.what();
      }
    }
  }
  fs::remove_all(scratch);
  EXPECT_GE(files, 10);
  EXPECT_GE(loaded, 6);  // the valid seeds
}

}  // namespace
}  // namespace ism
