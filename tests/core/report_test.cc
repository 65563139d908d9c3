#include "core/report/report.h"

#include <gtest/gtest.h>
#include <png.h>

#include <cstdio>
#include <fstream>
#include <sstream>

namespace ism {
namespace {

RecognitionResult sampleResult() {
  RecognitionResult r;
  Hypothesis h;
  h.category = "couch";
  h.score = 12.5f;
  h.threshold = 10.0f;
  h.center = Eigen::Vector3f(0.1f, 0.2f, 2.0f);
  h.box.center = h.center;
  h.box.size = Eigen::Vector3f(0.8f, 0.5f, 0.4f);
  h.support = 42;
  r.hypotheses.push_back(h);
  h.category = "dining_chair";
  h.passed_selection = false;
  r.rejected.push_back(h);
  r.timings.add("downsample", 3.0);
  r.timings.add("vote", 1.5);
  r.input_points = 1000;
  r.keypoints = 50;
  r.verified = 3;
  return r;
}

uint32_t bigEndian(const std::string& bytes, size_t at) {
  uint32_t v = 0;
  for (size_t i = 0; i < 4; ++i) v = v << 8 | static_cast<uint8_t>(bytes[at + i]);
  return v;
}

TEST(Report, JsonHasTheHypothesisFields) {
  const nlohmann::json j = toJson(sampleResult());
  ASSERT_EQ(j["hypotheses"].size(), 1u);
  const auto& h = j["hypotheses"][0];
  EXPECT_EQ(h["category"], "couch");
  EXPECT_FLOAT_EQ(h["score"].get<float>(), 12.5f);
  EXPECT_FLOAT_EQ(h["threshold"].get<float>(), 10.0f);
  EXPECT_FLOAT_EQ(h["center"][2].get<float>(), 2.0f);
  EXPECT_FLOAT_EQ(h["box"]["size"][0].get<float>(), 0.8f);
  EXPECT_EQ(h["box"]["rotation_wxyz"].size(), 4u);
  EXPECT_EQ(h["support"], 42);
  EXPECT_EQ(h["passed_selection"], true);
  EXPECT_EQ(j["rejected"][0]["passed_selection"], false);
  EXPECT_EQ(j["timings_ms"][1]["stage"], "vote");
  EXPECT_EQ(j["input_points"], 1000);
  EXPECT_EQ(j["keypoints"], 50);
  EXPECT_EQ(j["verified"], 3);
}

TEST(Report, TableListsEveryHypothesis) {
  const std::string table = hypothesesTable(sampleResult(), true);
  EXPECT_NE(table.find("couch"), std::string::npos);
  EXPECT_NE(table.find("12.500"), std::string::npos);
  EXPECT_NE(table.find("dining_chair"), std::string::npos);
  EXPECT_NE(table.find("rejected"), std::string::npos);
  EXPECT_NE(hypothesesTable(RecognitionResult{}).find("no hypotheses"), std::string::npos);
}

// A Kinect's lens (525 px focal length at 640 x 480) scaled to a picture of width x height.
PictureParams kinectLens(int width, int height) {
  PictureParams params;
  params.width = width;
  params.height = height;
  params.fx = params.fy = 525.0f * static_cast<float>(width) / 640.0f;
  params.cx = 0.5f * static_cast<float>(width - 1);
  params.cy = 0.5f * static_cast<float>(height - 1);
  return params;
}

// An organized frame through `lens` of a wall `depth` ahead, in the optical frame (z forward).
Scene wallFrame(const PictureParams& lens, float depth, uint8_t grey) {
  Scene scene;
  scene.image_width = lens.width;
  scene.image_height = lens.height;
  for (int v = 0; v < lens.height; ++v)
    for (int u = 0; u < lens.width; ++u) {
      scene.cloud->push_back(PointT((static_cast<float>(u) - lens.cx) * depth / lens.fx,
                                    (static_cast<float>(v) - lens.cy) * depth / lens.fy, depth, grey, grey, grey));
      scene.pixel_index.push_back(v * lens.width + u);
    }
  return scene;
}

TEST(Report, PictureIsAPngOfTheRequestedSizeWithTheBoxDrawn) {
  Scene scene;  // a wall 2 m in front of a sensor at the origin looking along +z
  for (float x = -1; x <= 1; x += 0.01f)
    for (float y = -0.8f; y <= 0.8f; y += 0.01f) scene.cloud->push_back(PointT(x, y, 2.0f, 0, 0, 0));
  const PictureParams params = kinectLens(320, 240);
  const std::string png = renderPicture(scene, sampleResult().hypotheses, params);
  ASSERT_GT(png.size(), 33u);
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_EQ(png.substr(12, 4), "IHDR");
  EXPECT_EQ(bigEndian(png, 16), 320u);
  EXPECT_EQ(bigEndian(png, 20), 240u);
  // The box adds the category colour to an otherwise grey picture, so it changes the bytes.
  EXPECT_NE(png, renderPicture(scene, {}, params));

  const std::string path = ::testing::TempDir() + "/report_test_picture.png";
  savePicture(scene, sampleResult().hypotheses, path, params);
  std::ifstream in(path, std::ios::binary);
  std::stringstream bytes;
  bytes << in.rdbuf();
  EXPECT_EQ(bytes.str(), png);
  std::remove(path.c_str());
}

// Grey level per pixel of a PNG made by renderPicture.
std::vector<uint8_t> decodeGrey(const std::string& png, int& width, int& height) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  EXPECT_TRUE(png_image_begin_read_from_memory(&image, png.data(), png.size()));
  image.format = PNG_FORMAT_GRAY;
  std::vector<uint8_t> grey(PNG_IMAGE_SIZE(image));
  EXPECT_TRUE(png_image_finish_read(&image, nullptr, grey.data(), 0, nullptr));
  width = static_cast<int>(image.width);
  height = static_cast<int>(image.height);
  return grey;
}

TEST(Report, CloudWithoutImageGridIsSeenAlongItsPointsUpUp) {
  // A room sample in the SUN RGB-D convention: sensor at the origin looking along +y, z up. A wall
  // 3 m ahead and a shelf high on it; drawn with the Kinect's optical frame (+z forward) the
  // picture would be black.
  Scene scene;
  for (float x = -1.5f; x <= 1.5f; x += 0.02f)
    for (float z = -1.2f; z <= 0.2f; z += 0.02f) scene.cloud->push_back(PointT(x, 3.0f, z, 0, 0, 0));
  for (float x = -0.5f; x <= 0.5f; x += 0.01f)
    for (float z = 0.8f; z <= 1.0f; z += 0.01f) scene.cloud->push_back(PointT(x, 2.8f, z, 0, 0, 0));
  PictureParams params;
  params.up = Eigen::Vector3f::UnitZ();
  int width = 0, height = 0;
  const std::vector<uint8_t> grey = decodeGrey(renderPicture(scene, {}, params), width, height);
  ASSERT_EQ(width, 640);
  ASSERT_EQ(height, 480);
  int lit = 0, lit_top = 0;
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u)
      if (grey[static_cast<size_t>(v * width + u)] > 0) ++lit, lit_top += v < height / 4;
  EXPECT_GT(lit, width * height / 5) << "the wall fills much of the picture";
  EXPECT_GT(lit_top, 0) << "the shelf, highest, is drawn at the top";
}

TEST(Report, AnImageWhosePoseLooksAwayFromItsPointsIsDrawnInItsOwnFrame) {
  // A 160x120 frame of a wall 2 m ahead in the optical frame (z forward), its pose turned 180
  // degrees about x (w 0, x 1), as PCL's test frames (office1.pcd) carry it.
  const PictureParams params = kinectLens(160, 120);
  Scene scene = wallFrame(params, 2.0f, 200);
  scene.has_color = true;
  scene.sensor_orientation = Eigen::Quaternionf(0, 1, 0, 0);
  int width = 0, height = 0;
  const std::vector<uint8_t> grey = decodeGrey(renderPicture(scene, {}, params), width, height);
  int lit = 0;
  for (const uint8_t g : grey) lit += g > 0;
  EXPECT_GT(lit, width * height * 9 / 10) << "the wall fills the picture";
}

TEST(Report, AMapIsDrawnFromAboveOneSide) {
  // A fused room without a sensor pose, z up, its origin on the floor in its middle, and a chair's
  // box on each side of the origin: from the origin they would be drawn behind the sensor, their
  // edges running off the picture; from above one side the whole room and both boxes show.
  Scene scene;
  for (float x = -3.0f; x <= 3.0f; x += 0.04f) {
    for (float y = -2.0f; y <= 2.0f; y += 0.04f) scene.cloud->push_back(PointT(x, y, 0.0f, 0, 0, 0));
    for (float z = 0.0f; z <= 2.4f; z += 0.04f) scene.cloud->push_back(PointT(x, 2.0f, z, 0, 0, 0));
  }
  std::vector<Hypothesis> chairs(2);
  for (int i = 0; i < 2; ++i) {
    chairs[static_cast<size_t>(i)].category = "office_chair";
    chairs[static_cast<size_t>(i)].box.center = Eigen::Vector3f(i == 0 ? -1.5f : 1.5f, 0.0f, 0.45f);
    chairs[static_cast<size_t>(i)].box.size = Eigen::Vector3f(0.6f, 0.6f, 0.9f);
  }
  PictureParams params;
  params.up = Eigen::Vector3f::UnitZ();
  int width = 0, height = 0;
  const std::vector<uint8_t> bare = decodeGrey(renderPicture(scene, {}, params), width, height);
  const std::vector<uint8_t> boxed = decodeGrey(renderPicture(scene, chairs, params), width, height);
  int lit = 0, drawn = 0, drawn_at_border = 0;
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const auto i = static_cast<size_t>(v * width + u);
      lit += bare[i] > 0;
      if (bare[i] == boxed[i]) continue;
      ++drawn;
      drawn_at_border += u < 3 || v < 3 || u >= width - 3 || v >= height - 3;
    }
  }
  EXPECT_GT(lit, width * height / 4) << "floor and wall fill much of the picture";
  EXPECT_GT(drawn, 100) << "both boxes are drawn";
  EXPECT_EQ(drawn_at_border, 0) << "no box edge runs off the picture";
}

TEST(Report, WithTheModelAVerifiedHypothesisShowsItsFittedShapeUnlessTheSceneHidesIt) {
  // A 160x120 frame of a wall 3 m ahead (optical frame). The category's one training shape is a
  // 0.4 m plate standing on its box's bottom; the box turns its up onto the optical axis, so the
  // plate faces the sensor: at 2 m it is drawn before the wall, at 4 m the wall hides it.
  const PictureParams params = kinectLens(160, 120);
  const Scene scene = wallFrame(params, 3.0f, 0);
  Model model;
  model.categories.resize(1);
  model.categories[0].name = "couch";
  TrainingObject plate;
  plate.size = Eigen::Vector3f(0.4f, 0.4f, 0.4f);
  for (float x = -0.2f; x <= 0.2f; x += 0.01f)
    for (float y = -0.2f; y <= 0.2f; y += 0.01f) plate.surface.emplace_back(x, y, 0.2f);
  model.categories[0].objects = {plate};
  const auto hypothesisAt = [](float depth) {
    Hypothesis h;
    h.category = "couch";
    h.box.center = Eigen::Vector3f(0, 0, depth);
    h.box.size = Eigen::Vector3f(0.4f, 0.4f, 0.4f);
    h.verification = Verification{};
    h.verification->object = 0;
    return h;
  };
  const auto changed = [&](const Hypothesis& h) {  // pixels the shape adds to the boxed picture
    int width = 0, height = 0;
    const std::vector<uint8_t> boxed = decodeGrey(renderPicture(scene, {h}, params), width, height);
    const std::vector<uint8_t> shaped = decodeGrey(renderPicture(scene, {h}, params, &model), width, height);
    int n = 0;
    for (size_t i = 0; i < boxed.size(); ++i) n += boxed[i] != shaped[i];
    return n;
  };
  EXPECT_GT(changed(hypothesisAt(2.0f)), 300) << "a 0.4 m plate at 2 m covers about 26 x 26 pixels";
  EXPECT_EQ(changed(hypothesisAt(4.0f)), 0) << "behind the wall";
  Hypothesis unverified = hypothesisAt(2.0f);
  unverified.verification.reset();
  EXPECT_EQ(changed(unverified), 0);
}

TEST(Report, DebugPlyHoldsKeypointsVotesAndCentres) {
  Model model;
  model.categories.resize(1);
  model.categories[0].name = "couch";
  RecognitionResult r = sampleResult();
  r.keypoint_positions = {Eigen::Vector3f::Zero(), Eigen::Vector3f::Ones()};
  r.votes = {{Eigen::Vector3f(0.1f, 0.2f, 2.0f), 0.5f, 0, 0}, {Eigen::Vector3f(0.1f, 0.2f, 2.1f), 1.0f, 1, 0}};
  const std::string path = ::testing::TempDir() + "/report_test_debug.ply";
  saveDebugPly(model, r, path);
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_NE(text.str().find("element vertex 5"), std::string::npos);  // 2 keypoints + 2 votes + 1 centre
  std::remove(path.c_str());
}

TEST(Report, CategoryColoursAreStable) {
  EXPECT_EQ(categoryColor("couch"), categoryColor("couch"));
  EXPECT_NE(categoryColor("couch"), categoryColor("dining_table"));
}

}  // namespace
}  // namespace ism
