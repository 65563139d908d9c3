// The server's wire -> Scene conversion (server/conversion.cc) in process: a cloud decodes to
// exactly what core's sceneFromPacked makes of the same bytes, also when a worker's buffers
// are reused from one scene to the next, and bad clouds fail with the same messages.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "core/common/error.h"
#include "core/io/cloud_io.h"
#include "server/conversion.h"

namespace ism::testing {
namespace {

using server::InputLimits;
using server::SceneBuffers;
using server::sceneFromProto;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

struct WireCloud {
  std::vector<float> xyz;
  std::vector<uint8_t> rgb;  // empty: no colour
  uint32_t width = 0, height = 0;

  v1::Scene message() const {
    v1::Scene scene;
    auto* cloud = scene.mutable_cloud();
    cloud->set_xyz(reinterpret_cast<const char*>(xyz.data()), xyz.size() * sizeof(float));
    if (!rgb.empty()) cloud->set_rgb(reinterpret_cast<const char*>(rgb.data()), rgb.size());
    cloud->set_width(width);
    cloud->set_height(height);
    return scene;
  }
  // What core makes of the same bytes.
  Scene reference() const {
    const size_t count = xyz.size() / 3;
    const bool unorganized = width == 0 && height == 0;
    Scene scene = sceneFromPacked(xyz.data(), count, rgb.empty() ? nullptr : rgb.data(),
                                  unorganized ? static_cast<int>(count) : static_cast<int>(width),
                                  unorganized ? 1 : static_cast<int>(height));
    scene.source = "request";
    return scene;
  }
};

// `width` x `height` points (unorganized when both are 0: `points` of them), about a fifth
// of them NaN or Inf in one coordinate.
WireCloud randomCloud(uint32_t width, uint32_t height, size_t points, bool color, unsigned seed) {
  WireCloud out;
  out.width = width;
  out.height = height;
  const size_t count = width == 0 && height == 0 ? points : size_t{width} * height;
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> coordinate(-3.0f, 3.0f);
  std::uniform_int_distribution<int> byte(0, 255), hole(0, 9);
  for (size_t i = 0; i < count; ++i) {
    float p[3] = {coordinate(random), coordinate(random), coordinate(random)};
    const int h = hole(random);
    if (h == 0) p[0] = p[1] = p[2] = kNaN;
    if (h == 1) p[h % 3] = std::numeric_limits<float>::infinity();
    out.xyz.insert(out.xyz.end(), p, p + 3);
    if (color) {
      for (int c = 0; c < 3; ++c) out.rgb.push_back(static_cast<uint8_t>(byte(random)));
    }
  }
  return out;
}

void expectSameScene(const Scene& actual, const Scene& expected) {
  ASSERT_TRUE(actual.cloud);
  ASSERT_EQ(actual.cloud->size(), expected.cloud->size());
  EXPECT_EQ(actual.cloud->width, expected.cloud->width);
  EXPECT_EQ(actual.cloud->height, expected.cloud->height);
  EXPECT_EQ(actual.cloud->is_dense, expected.cloud->is_dense);
  // Every field of every point, bit for bit: x, y, z, the 4th coordinate and r, g, b, alpha.
  size_t differing = 0;
  for (size_t i = 0; i < expected.cloud->size(); ++i) {
    const PointT &a = (*actual.cloud)[i], &e = (*expected.cloud)[i];
    differing += std::memcmp(a.data, e.data, sizeof a.data) != 0 || a.rgba != e.rgba;
  }
  EXPECT_EQ(differing, 0u);
  EXPECT_EQ(actual.has_color, expected.has_color);
  EXPECT_EQ(actual.image_width, expected.image_width);
  EXPECT_EQ(actual.image_height, expected.image_height);
  EXPECT_EQ(actual.pixel_index, expected.pixel_index);
  EXPECT_EQ(actual.source, expected.source);
  EXPECT_TRUE(actual.sensor_origin.isZero());
  EXPECT_TRUE(actual.sensor_orientation.coeffs().isApprox(Eigen::Quaternionf::Identity().coeffs()));
}

TEST(Conversion, PointsBeyondTheRangeAreDroppedWithTheirPixels) {
  WireCloud wire;
  wire.xyz = {0, 0, 1, 0, 0, 300, 1, 0, 1, kNaN, 0, 0, 0, 1e30f, 0, 2, 2, 2};
  wire.width = 3;
  wire.height = 2;
  v1::Scene message = wire.message();
  message.mutable_sensor_origin()->set_z(0.5f);
  Scene scene = sceneFromProto(message, InputLimits{});
  EXPECT_EQ(server::dropPointsBeyondRange(&scene, 100.0f), 2u);
  ASSERT_EQ(scene.cloud->size(), 3u);
  EXPECT_EQ(scene.cloud->width, 3u);
  EXPECT_EQ(scene.pixel_index, (std::vector<int>{0, 2, 5}));
  EXPECT_EQ(scene.cloud->at(2).getVector3fMap(), Eigen::Vector3f(2, 2, 2));

  // The range counts from the sensor origin, not from (0, 0, 0).
  message.mutable_sensor_origin()->set_z(1000.0f);
  Scene far = sceneFromProto(message, InputLimits{});
  EXPECT_EQ(server::dropPointsBeyondRange(&far, 800.0f), 4u);
  EXPECT_EQ(far.pixel_index, (std::vector<int>{1}));

  Scene none = sceneFromProto(message, InputLimits{});
  try {
    server::dropPointsBeyondRange(&none, 10.0f);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidInput);
    EXPECT_NE(std::string(e.what()).find("all 5 points are farther than 10 m from scene.sensor_origin (the nearest "
                                         "at 700 m)"),
              std::string::npos)
        << e.what();
  }
}

TEST(Conversion, CloudDecodesAsCoreDoes) {
  const InputLimits limits;
  for (const WireCloud& cloud : {randomCloud(64, 48, 0, true, 1), randomCloud(64, 48, 0, false, 2),
                                 randomCloud(0, 0, 1000, true, 3), randomCloud(0, 0, 777, false, 4),
                                 randomCloud(1000, 1, 0, true, 5)}) {
    SCOPED_TRACE(std::to_string(cloud.width) + "x" + std::to_string(cloud.height) +
                 (cloud.rgb.empty() ? " xyz" : " xyzrgb"));
    expectSameScene(sceneFromProto(cloud.message(), limits), cloud.reference());
  }
}

// One worker's buffers through scenes of every kind, in an order that shrinks and grows them.
TEST(Conversion, ReusedBuffersDecodeEveryScene) {
  const InputLimits limits;
  SceneBuffers buffers;
  const std::vector<WireCloud> clouds{randomCloud(64, 48, 0, true, 11), randomCloud(0, 0, 100, false, 12),
                                      randomCloud(80, 60, 0, false, 13), randomCloud(32, 24, 0, true, 14),
                                      randomCloud(0, 0, 5000, true, 15)};
  const PointT* previous = nullptr;
  for (int round = 0; round < 2; ++round) {
    for (size_t i = 0; i < clouds.size(); ++i) {
      SCOPED_TRACE("round " + std::to_string(round) + ", cloud " + std::to_string(i));
      Scene scene = sceneFromProto(clouds[i].message(), limits, &buffers);
      expectSameScene(scene, clouds[i].reference());
      // Once the buffers hold the largest scene, every later one lives in the same memory.
      if (round == 1) {
        if (previous != nullptr) EXPECT_EQ(scene.cloud->points.data(), previous);
        previous = scene.cloud->points.data();
      }
      buffers.recycle(scene);
      EXPECT_FALSE(scene.cloud);
      ASSERT_TRUE(buffers.cloud);
      EXPECT_TRUE(buffers.cloud->empty());
      EXPECT_TRUE(buffers.pixel_index.empty());
    }
  }
}

TEST(Conversion, SharedOrHugeCloudsAreNotRecycled) {
  const InputLimits limits;
  SceneBuffers buffers;
  Scene scene = sceneFromProto(randomCloud(16, 12, 0, true, 21).message(), limits, &buffers);
  const Cloud::Ptr kept = scene.cloud;  // someone still uses it
  const size_t points = kept->size();
  buffers.recycle(scene);
  EXPECT_FALSE(buffers.cloud);
  EXPECT_EQ(kept->size(), points);

  Scene huge;
  huge.cloud->points.reserve(SceneBuffers::kMaxKeptPoints + 1);
  huge.pixel_index.reserve(SceneBuffers::kMaxKeptPoints + 1);
  buffers.recycle(huge);
  EXPECT_FALSE(buffers.cloud);
  EXPECT_LE(buffers.pixel_index.capacity(), SceneBuffers::kMaxKeptPoints);
}

// The failures the integration tests check over gRPC, here with buffers in play: a failed
// decode leaves the next one unharmed.
TEST(Conversion, BadCloudsFailWithTheirMessagesAndBuffersRecover) {
  InputLimits limits;
  limits.max_points = 10000;
  SceneBuffers buffers;
  const auto failure = [&](const v1::Scene& message) -> std::string {
    try {
      sceneFromProto(message, limits, &buffers);
    } catch (const Error& e) {
      return e.what();
    }
    return "no error";
  };
  WireCloud all_nan;
  all_nan.xyz.assign(3 * 50, kNaN);
  EXPECT_NE(failure(all_nan.message()).find("none of its 50 points is finite"), std::string::npos);
  WireCloud wrong_grid = randomCloud(4, 3, 0, false, 31);
  wrong_grid.width = 5;
  EXPECT_NE(failure(wrong_grid.message()).find("declared 5x3 = 15 points but xyz has 12"), std::string::npos);
  WireCloud wrong_rgb = randomCloud(4, 3, 0, true, 32);
  wrong_rgb.rgb.pop_back();
  EXPECT_NE(failure(wrong_rgb.message()).find("scene.cloud.rgb has 35 bytes but xyz has 12 points"),
            std::string::npos);
  EXPECT_NE(failure(randomCloud(0, 0, 10001, false, 33).message()).find("more than the server's limit of 10000"),
            std::string::npos);
  v1::Scene ragged = randomCloud(0, 0, 4, false, 34).message();
  ragged.mutable_cloud()->mutable_xyz()->pop_back();
  EXPECT_NE(failure(ragged).find("not a multiple of 12"), std::string::npos);

  const WireCloud good = randomCloud(40, 30, 0, true, 35);
  expectSameScene(sceneFromProto(good.message(), limits, &buffers), good.reference());
}

}  // namespace
}  // namespace ism::testing
