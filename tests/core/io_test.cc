#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <png.h>
#include <unistd.h>

#include <filesystem>
#include <limits>
#include <random>

#include "core/common/error.h"
#include "core/io/cloud_io.h"
#include "core/io/depth_png.h"
#include "core/io/file_bytes.h"
#include "tests/common/expect_error.h"
#include "tests/common/png_bomb.h"

namespace ism {
namespace {

namespace fs = std::filesystem;

// A fresh directory per test, removed afterwards.
class IoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / (std::string("ism_io_test_") + info->name() + "_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

using ism::testing::expectError;

PointT colored(float x, float y, float z, uint8_t r, uint8_t g, uint8_t b) {
  PointT p;
  p.x = x, p.y = y, p.z = z;
  p.r = r, p.g = g, p.b = b;
  return p;
}

std::string encode8BitPng(png_uint_32 format) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = 4;
  image.height = 3;
  image.format = format;
  std::vector<uint8_t> pixels(PNG_IMAGE_SIZE(image), 7);
  png_alloc_size_t size = 0;
  EXPECT_TRUE(png_image_write_to_memory(&image, nullptr, &size, 0, pixels.data(), 0, nullptr));
  std::string bytes(size, '\0');
  EXPECT_TRUE(png_image_write_to_memory(&image, bytes.data(), &size, 0, pixels.data(), 0, nullptr));
  return bytes;
}

TEST_F(IoTest, PcdRoundTripKeepsColourAndViewpoint) {
  Scene scene;
  scene.cloud->push_back(colored(0.1f, -0.2f, 1.5f, 255, 0, 10));
  scene.cloud->push_back(colored(-1.0f, 0.5f, 2.25f, 1, 128, 254));
  scene.has_color = true;
  scene.sensor_origin = Eigen::Vector3f(0.5f, -1.0f, 2.0f);
  scene.sensor_orientation = Eigen::Quaternionf(Eigen::AngleAxisf(0.7f, Eigen::Vector3f(1, 2, 3).normalized()));
  savePcd(scene, path("colour.pcd"));

  const Scene loaded = loadCloudFile(path("colour.pcd"));
  EXPECT_TRUE(loaded.has_color);
  EXPECT_EQ(loaded.source, path("colour.pcd"));
  EXPECT_TRUE(loaded.pixel_index.empty());
  ASSERT_EQ(loaded.cloud->size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(loaded.cloud->at(i).getVector3fMap(), scene.cloud->at(i).getVector3fMap());
    EXPECT_EQ(loaded.cloud->at(i).getRGBVector3i(), scene.cloud->at(i).getRGBVector3i());
  }
  EXPECT_TRUE(loaded.sensor_origin.isApprox(scene.sensor_origin));
  EXPECT_NEAR(loaded.sensor_orientation.angularDistance(scene.sensor_orientation), 0.0f, 1e-5f);
}

TEST_F(IoTest, PcdWithoutColourIsNotColoured) {
  pcl::PointCloud<pcl::PointXYZ> cloud;
  cloud.push_back({1.0f, 2.0f, 3.0f});
  pcl::io::savePCDFileBinary(path("plain.pcd"), cloud);
  const Scene loaded = loadCloudFile(path("plain.pcd"));
  EXPECT_FALSE(loaded.has_color);
  ASSERT_EQ(loaded.cloud->size(), 1u);
  EXPECT_EQ(loaded.cloud->at(0).getVector3fMap(), Eigen::Vector3f(1, 2, 3));
}

TEST_F(IoTest, OrganizedPcdDropsNonFiniteAndKeepsPixelIndex) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  pcl::PointCloud<pcl::PointXYZ> cloud(3, 2);  // width 3, height 2
  const float xs[6] = {0, nan, 2, inf, 4, 5};
  for (int i = 0; i < 6; ++i) cloud[i] = pcl::PointXYZ(xs[i], 1.0f, 2.0f);
  cloud.is_dense = false;
  pcl::io::savePCDFileBinary(path("organized.pcd"), cloud);

  const Scene loaded = loadCloudFile(path("organized.pcd"));
  EXPECT_EQ(loaded.image_width, 3);
  EXPECT_EQ(loaded.image_height, 2);
  EXPECT_EQ(loaded.pixel_index, (std::vector<int>{0, 2, 4, 5}));
  ASSERT_EQ(loaded.cloud->size(), 4u);
  EXPECT_EQ(loaded.cloud->at(1).x, 2.0f);
  EXPECT_EQ(loaded.cloud->at(3).x, 5.0f);
}

TEST_F(IoTest, OrganizedSceneSurvivesSaveAndLoad) {
  const std::vector<uint16_t> depth = {0, 1000, 2000, 0, 1500, 0};
  const Scene scene = depthToScene(depth.data(), 3, 2, DepthIntrinsics{});
  savePcd(scene, path("depth.pcd"));
  const Scene loaded = loadCloudFile(path("depth.pcd"));
  EXPECT_FALSE(loaded.has_color);
  EXPECT_EQ(loaded.image_width, 3);
  EXPECT_EQ(loaded.image_height, 2);
  EXPECT_EQ(loaded.pixel_index, (std::vector<int>{1, 2, 4}));
  ASSERT_EQ(loaded.cloud->size(), scene.cloud->size());
  for (size_t i = 0; i < scene.cloud->size(); ++i) {
    EXPECT_EQ(loaded.cloud->at(i).getVector3fMap(), scene.cloud->at(i).getVector3fMap());
  }
}

TEST_F(IoTest, PlyRoundTripAsciiAndBinaryWithAndWithoutColour) {
  const std::vector<Eigen::Vector3f> points = {{0.125f, -2.5f, 3.0f}, {1e-3f, 4.75f, -0.5f}, {7, 8, 9}};
  const std::vector<Eigen::Vector3i> colors = {{255, 0, 0}, {0, 300, 17}, {-5, 1, 254}};  // clamped to 0..255
  const std::vector<Eigen::Vector3i> expected_colors = {{255, 0, 0}, {0, 255, 17}, {0, 1, 254}};
  for (PlyEncoding encoding : {PlyEncoding::kAscii, PlyEncoding::kBinary}) {
    for (bool with_color : {true, false}) {
      SCOPED_TRACE(std::string(encoding == PlyEncoding::kAscii ? "ascii" : "binary") +
                   (with_color ? " colour" : " plain"));
      const std::string file = path("points.ply");
      savePlyPoints(points, with_color ? colors : std::vector<Eigen::Vector3i>{}, file, encoding);
      const Scene loaded = loadCloudFile(file);
      EXPECT_EQ(loaded.has_color, with_color);
      ASSERT_EQ(loaded.cloud->size(), points.size());
      for (size_t i = 0; i < points.size(); ++i) {
        EXPECT_EQ(loaded.cloud->at(i).getVector3fMap(), points[i]);
        if (with_color) {
          EXPECT_EQ(loaded.cloud->at(i).getRGBVector3i(), expected_colors[i]);
        }
      }
    }
  }
}

TEST_F(IoTest, PlyWithDoubleCoordinatesIsRead) {
  // Open3D and several meshing tools write float64 coordinates.
  writeFileBytes(path("double.ply"),
                 "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
                 "property double z\nend_header\n0.5 1.5 2.5\nnan 0 1\n");
  const Scene loaded = loadCloudFile(path("double.ply"));
  ASSERT_EQ(loaded.cloud->size(), 1u);
  EXPECT_EQ(loaded.cloud->at(0).getVector3fMap(), Eigen::Vector3f(0.5f, 1.5f, 2.5f));
}

TEST_F(IoTest, UnreadableFilesNameTheFile) {
  expectError([&] { loadCloudFile(path("missing.pcd")); }, ErrorCode::kNotFound, path("missing.pcd"));
  expectError([&] { loadDepthPng(path("missing.png"), {}); }, ErrorCode::kNotFound, path("missing.png"));
  writeFileBytes(path("garbage.pcd"), "this is not a point cloud\n\x01\x02");
  expectError([&] { loadCloudFile(path("garbage.pcd")); }, ErrorCode::kInvalidInput, path("garbage.pcd"));
  writeFileBytes(path("garbage.ply"), "ply\nformat nonsense\n");
  expectError([&] { loadCloudFile(path("garbage.ply")); }, ErrorCode::kInvalidInput, path("garbage.ply"));
  writeFileBytes(path("nodata.pcd"), "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                                    "WIDTH 1\nHEIGHT 1\nPOINTS 1\n");
  expectError([&] { loadCloudFile(path("nodata.pcd")); }, ErrorCode::kInvalidInput, "the header has no DATA line");
  pcl::PointCloud<pcl::PointXYZ> cloud;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> coordinate(-1.0f, 1.0f);
  for (int i = 0; i < 1000; ++i) cloud.push_back({coordinate(rng), coordinate(rng), coordinate(rng)});
  for (bool compressed : {false, true}) {
    const std::string file = path(compressed ? "compressed.pcd" : "binary.pcd");
    compressed ? pcl::io::savePCDFileBinaryCompressed(file, cloud) : pcl::io::savePCDFileBinary(file, cloud);
    const std::string bytes = readFileBytes(file);
    writeFileBytes(file, bytes.substr(0, bytes.size() - 200));
    expectError([&] { loadCloudFile(file); }, ErrorCode::kInvalidInput, file + ": malformed PCD file");
  }
  writeFileBytes(path("cloud.xyz"), "1 2 3\n");
  expectError([&] { loadCloudFile(path("cloud.xyz")); }, ErrorCode::kInvalidInput, "'.xyz'");
  fs::create_directories(path("dir.pcd"));
  expectError([&] { loadCloudFile(path("dir.pcd")); }, ErrorCode::kIo, path("dir.pcd"));
}

// Inputs tests/fuzz found crashing the readers (an escaping std::out_of_range from PCL, a read
// past the point data, PCL's asserts on incomplete or non-uchar PLY colour, on a vertex list
// property and on a header line starting with a blank, a compressed body smaller than the header's points,
// gigabytes allocated for a PLY's stated vertex count): each must be a named error.
TEST_F(IoTest, FuzzFindingsAreRefusedWithAnError) {
  writeFileBytes(path("only_data.pcd"), "DATA");
  expectError([&] { loadCloudFile(path("only_data.pcd")); }, ErrorCode::kInvalidInput, path("only_data.pcd"));
  writeFileBytes(path("size_type.pcd"), "VERSION .7\nFIELDS x y z\nSIZE 8 40 0\nPOINTS 2\nDATA ascii\n"
                                        "0.0 0.0 1.0\n0.1 0.0 1.05\n");
  expectError([&] { loadCloudFile(path("size_type.pcd")); }, ErrorCode::kInvalidInput, path("size_type.pcd"));
  // One vertex with x, y, z and the given properties and values.
  const auto vertexPly = [](const std::string& properties, const std::string& values) {
    return "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n" +
           properties + "end_header\n1 2 3" + values + "\n";
  };
  const std::string rgb = "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  const std::pair<std::string, std::string> refused[] = {
      {"property uchar blue\n", "red, green and blue"},
      {"property uchar diffuse_blue\n", "red, green and blue"},
      {rgb + "property uchar diffuse_red\nproperty uchar diffuse_green\nproperty uchar diffuse_blue\n",
       "red, green and blue"},
      {"property uchar blue\nproperty uchar green\nproperty uchar red\n", "red before blue"},
      {"property uchar alpha\n" + rgb, "alpha after red"},
      {"property uchar red\nproperty uchar green\nproperty uchar green\n", "red, green and blue"},
      {"property list uchar int ids\n", "list property"},
      {"property char red\nproperty uchar green\nproperty uchar blue\n", "red is char"},
  };
  for (const auto& [properties, needle] : refused) {
    writeFileBytes(path("colour.ply"), vertexPly(properties, " 4 5 6 7 8 9"));
    expectError([&] { loadCloudFile(path("colour.ply")); }, ErrorCode::kInvalidInput, needle);
  }
  writeFileBytes(path("diffuse.ply"),
                 vertexPly("property uchar diffuse_red\nproperty uchar diffuse_green\nproperty uchar diffuse_blue\n",
                           " 4 5 6"));
  EXPECT_EQ(loadCloudFile(path("diffuse.ply")).cloud->size(), 1u) << "the three diffuse channels are colour";
  writeFileBytes(path("two_vertex.ply"), "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                                         "element vertex 1\nproperty float y\nend_header\n1\n2\n");
  expectError([&] { loadCloudFile(path("two_vertex.ply")); }, ErrorCode::kInvalidInput, "second vertex element");
  writeFileBytes(path("obj_info.ply"), "ply\n\vobj_info x\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                                       "property float y\nproperty float z\nend_header\n1 2 3\n");
  expectError([&] { loadCloudFile(path("obj_info.ply")); }, ErrorCode::kInvalidInput, "line 2 starts with a blank");
  for (const char* count : {"-2", "4000000000", "x"}) {
    writeFileBytes(path("count.ply"), std::string("ply\nformat binary_little_endian 1.0\nelement vertex ") + count +
                                          "\nproperty float x\nproperty float y\nproperty float z\nend_header\n");
    expectError([&] { loadCloudFile(path("count.ply")); }, ErrorCode::kInvalidInput,
                std::string("vertex count '") + count + "' does not fit a file of");
  }
  // COUNT 2 makes x 8 bytes: 6 points need 96 bytes, the body unpacks to 72 (6 x 12). The LZF
  // stream is three literal runs (a control byte of length - 1, then the bytes): 32 + 32 + 8.
  std::string compressed = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 2 1 1\nWIDTH 6\nHEIGHT 1\n"
                           "POINTS 6\nDATA binary_compressed\n";
  const uint32_t body_sizes[2] = {75, 72};
  compressed.append(reinterpret_cast<const char*>(body_sizes), sizeof body_sizes);
  for (int run : {32, 32, 8}) compressed.append(1, static_cast<char>(run - 1)).append(run, '\0');
  writeFileBytes(path("compressed.pcd"), compressed);
  expectError([&] { loadCloudFile(path("compressed.pcd")); }, ErrorCode::kInvalidInput,
              "compressed body unpacks to 72 bytes, the header's points need 96");
}

TEST_F(IoTest, CloudWithoutFiniteOrCoordinateFieldsIsRejected) {
  writeFileBytes(path("nan.ply"),
                 "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                 "property float z\nend_header\nnan nan nan\n");
  expectError([&] { loadCloudFile(path("nan.ply")); }, ErrorCode::kInvalidInput, "none of its 1 points is finite");
  writeFileBytes(path("noz.ply"),
                 "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n");
  expectError([&] { loadCloudFile(path("noz.ply")); }, ErrorCode::kInvalidInput, "no 'z' field");
}

TEST_F(IoTest, DepthPngRoundTrip) {
  DepthPng image;
  image.width = 7;
  image.height = 5;
  std::mt19937 rng(3);
  for (int i = 0; i < image.width * image.height; ++i) image.pixels.push_back(static_cast<uint16_t>(rng()));
  image.pixels[0] = 0;
  image.pixels[1] = 65535;
  const std::string bytes = encodeDepthPng16(image);
  const DepthPng decoded = decodeDepthPng16(bytes, "memory");
  EXPECT_EQ(decoded.width, 7);
  EXPECT_EQ(decoded.height, 5);
  EXPECT_EQ(decoded.pixels, image.pixels);

  writeFileBytes(path("depth.png"), bytes);
  EXPECT_EQ(readFileBytes(path("depth.png")), bytes);
}

TEST_F(IoTest, KnownDepthPixelMapsToItsPoint) {
  DepthPng image;
  image.width = 640;
  image.height = 480;
  image.pixels.assign(640 * 480, 0);
  const int u = 400, v = 100;
  image.pixels[v * 640 + u] = 12500;  // 2.5 m at 5000 units per metre (TUM)
  DepthIntrinsics intrinsics;
  intrinsics.fx = 525.0f;
  intrinsics.fy = 520.0f;
  intrinsics.cx = 319.5f;
  intrinsics.cy = 239.5f;
  intrinsics.depth_scale = 5000.0f;
  const Scene scene = decodeDepthPng(encodeDepthPng16(image), intrinsics, "frame");
  EXPECT_EQ(scene.image_width, 640);
  EXPECT_EQ(scene.image_height, 480);
  EXPECT_EQ(scene.pixel_index, std::vector<int>{v * 640 + u});
  ASSERT_EQ(scene.cloud->size(), 1u);
  const Eigen::Vector3f expected((400 - 319.5f) * 2.5f / 525.0f, (100 - 239.5f) * 2.5f / 520.0f, 2.5f);
  EXPECT_TRUE(scene.cloud->at(0).getVector3fMap().isApprox(expected, 1e-6f)) << scene.cloud->at(0);
  EXPECT_TRUE(scene.sensor_origin.isZero());
}

TEST_F(IoTest, NonDepthPngsAreRejectedWithWhatTheyAre) {
  expectError([&] { decodeDepthPng16(encode8BitPng(PNG_FORMAT_GRAY), "grey.png"); }, ErrorCode::kInvalidInput,
              "grey.png: PNG is 8-bit greyscale, expected a 16-bit single-channel depth image");
  expectError([&] { decodeDepthPng16(encode8BitPng(PNG_FORMAT_RGB), "colour.png"); }, ErrorCode::kInvalidInput,
              "8-bit RGB");
  expectError([&] { decodeDepthPng16("GIF89a........", "anim.gif"); }, ErrorCode::kInvalidInput, "anim.gif: not a PNG");
}

TEST_F(IoTest, TruncatedOrCorruptPngIsRejected) {
  DepthPng image;
  image.width = 64;
  image.height = 64;
  for (int i = 0; i < 64 * 64; ++i) image.pixels.push_back(static_cast<uint16_t>(i * 37));
  const std::string bytes = encodeDepthPng16(image);
  expectError([&] { decodeDepthPng16(bytes.substr(0, bytes.size() / 2), "half.png"); }, ErrorCode::kInvalidInput,
              "half.png: broken PNG data: data is truncated");
  expectError([&] { decodeDepthPng16(bytes.substr(0, 20), "header.png"); }, ErrorCode::kInvalidInput,
              "header.png: broken PNG header");
  std::string flipped = bytes;
  flipped[bytes.size() / 2] = static_cast<char>(flipped[bytes.size() / 2] ^ 0x5A);
  expectError([&] { decodeDepthPng16(flipped, "flipped.png"); }, ErrorCode::kInvalidInput, "flipped.png: broken PNG");
}

void appendToString(png_structp png, png_bytep data, png_size_t length) {
  static_cast<std::string*>(png_get_io_ptr(png))->append(reinterpret_cast<const char*>(data), length);
}

// encodeDepthPng16 never interlaces; other encoders may.
std::string encodeInterlaced(const DepthPng& image) {
  std::string out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  png_set_write_fn(png, &out, appendToString, nullptr);
  png_set_IHDR(png, info, image.width, image.height, 16, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_ADAM7,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  png_set_swap(png);
  std::vector<png_bytep> rows;
  for (int r = 0; r < image.height; ++r) {
    rows.push_back(reinterpret_cast<png_bytep>(const_cast<uint16_t*>(image.pixels.data() + r * image.width)));
  }
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

TEST_F(IoTest, InterlacedDepthPngsDecode) {
  for (const auto& [width, height] : std::vector<std::pair<int, int>>{{1, 1}, {13, 7}, {3, 10}, {64, 48}}) {
    DepthPng image;
    image.width = width;
    image.height = height;
    for (int i = 0; i < width * height; ++i) image.pixels.push_back(static_cast<uint16_t>(i * 977 + 1));
    const DepthPng decoded = decodeDepthPng16(encodeInterlaced(image), "interlaced.png");
    EXPECT_EQ(decoded.pixels, image.pixels) << width << "x" << height;
  }
}

// A 1x1 image whose data inflates to 64 MB: refused once it passes the 3 bytes (a filter byte
// and one pixel) the header allows, not inflated to its end.
TEST_F(IoTest, ADecompressionBombIsRefusedAtTheSizeItsHeaderAllows) {
  const std::string bomb = ism::testing::depthPngBomb(64);
  ASSERT_LT(bomb.size(), 100u * 1024);
  int asked = 0;
  expectError([&] { decodeDepthPng16(bomb, "bomb.png", [&] { return ++asked < 0; }); }, ErrorCode::kInvalidInput,
              "bomb.png: the PNG's image data inflates to more than the 3 bytes a 1x1 16-bit image holds");
  EXPECT_EQ(asked, 0);  // stopped long before a check for the deadline was due
}

TEST_F(IoTest, DecodingStopsWhenTheCallerGivesUp) {
  DepthPng image;
  image.width = 64;
  image.height = 64;
  image.pixels.assign(64 * 64, 1234);
  const std::string bytes = encodeDepthPng16(image);
  int rows = 0;
  expectError([&] { decodeDepthPng16(bytes, "frame.png", [&] { return ++rows == 10; }); }, ErrorCode::kCancelled,
              "stopped during PNG decoding");
  EXPECT_EQ(rows, 10);
  EXPECT_EQ(decodeDepthPng16(bytes, "frame.png", [] { return false; }).pixels, image.pixels);
}

TEST_F(IoTest, EncodeRejectsInconsistentImage) {
  DepthPng image;
  image.width = 4;
  image.height = 4;
  image.pixels.assign(15, 1);
  expectError([&] { encodeDepthPng16(image); }, ErrorCode::kInvalidInput, "has 15 pixels, expected width*height = 16");
}

TEST_F(IoTest, PackedPointsValidateSizesAndKeepOrganization) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<float> xyz = {0, 0, 1, nan, 0, 1, 1, 1, 1, 2, 2, 2};
  const std::vector<uint8_t> rgb = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
  const Scene scene = sceneFromPacked(xyz.data(), 4, rgb.data(), 2, 2);
  EXPECT_TRUE(scene.has_color);
  EXPECT_EQ(scene.pixel_index, (std::vector<int>{0, 2, 3}));
  ASSERT_EQ(scene.cloud->size(), 3u);
  EXPECT_EQ(scene.cloud->at(1).getRGBVector3i(), Eigen::Vector3i(7, 8, 9));
  EXPECT_EQ(scene.cloud->at(2).getVector3fMap(), Eigen::Vector3f(2, 2, 2));

  const Scene flat = sceneFromPacked(xyz.data(), 4, nullptr, 4, 1);
  EXPECT_FALSE(flat.has_color);
  EXPECT_TRUE(flat.pixel_index.empty());
  EXPECT_EQ(flat.cloud->size(), 3u);

  expectError([&] { sceneFromPacked(xyz.data(), 4, nullptr, 3, 2); }, ErrorCode::kInvalidInput,
              "request: width*height = 3*2 = 6 does not match the 4 points sent");
  expectError([&] { sceneFromPacked(xyz.data(), 4, nullptr, 0, 1); }, ErrorCode::kInvalidInput, "must be positive");
  expectError([&] { sceneFromPacked(xyz.data(), 0, nullptr, 0, 1); }, ErrorCode::kInvalidInput, "no points");
}

TEST_F(IoTest, DepthToSceneRejectsBadIntrinsicsAndEmptyFrames) {
  const std::vector<uint16_t> zeros(6, 0);
  expectError([&] { depthToScene(zeros.data(), 3, 2, DepthIntrinsics{}, "blank"); }, ErrorCode::kInvalidInput,
              "blank: none of its 6 points is finite");
  DepthIntrinsics bad;
  bad.depth_scale = 0.0f;
  expectError([&] { depthToScene(zeros.data(), 3, 2, bad, "frame"); }, ErrorCode::kInvalidInput, "depth_scale=0");
}

// The shipped TUM frame's PCD was back-projected from its depth PNG with the intrinsics in its
// JSON, so both readers must produce the same points at the same pixels.
TEST(IoRealData, TumDeskPcdMatchesItsDepthPng) {
  const std::string dir = std::string(ISM_SHARED_DATA_DIR) + "/real/kinect/";
  if (!fs::exists(dir + "tum_desk.pcd") || !fs::exists(dir + "tum_desk_depth.png")) {
    GTEST_SKIP() << "shared data not present at " << dir;
  }
  const Scene cloud = loadCloudFile(dir + "tum_desk.pcd");
  DepthIntrinsics intrinsics;
  intrinsics.depth_scale = 5000.0f;
  const Scene depth = loadDepthPng(dir + "tum_desk_depth.png", intrinsics);
  EXPECT_TRUE(cloud.has_color);
  EXPECT_EQ(cloud.image_width, 640);
  EXPECT_EQ(cloud.image_height, 480);
  ASSERT_EQ(cloud.pixel_index, depth.pixel_index);
  float worst = 0.0f;
  for (size_t i = 0; i < cloud.cloud->size(); ++i) {
    worst = std::max(worst, (cloud.cloud->at(i).getVector3fMap() - depth.cloud->at(i).getVector3fMap()).norm());
  }
  EXPECT_LT(worst, 1e-4f);
}

}  // namespace
}  // namespace ism
