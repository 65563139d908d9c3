// The up direction, the floor and the walls: on rendered rooms with exact ground truth, seen from
// tilted cameras in the sensor's own frame, and on the real Kinect frame whose floor was levelled
// by hand.
#include "core/gravity/gravity.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "core/common/error.h"
#include "core/frontend/frontend.h"
#include "core/io/cloud_io.h"
#include "core/scanner/scanner.h"
#include "tests/common/synthetic_furniture.h"

namespace ism {
namespace {

float degreesBetween(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0f, 1.0f)) * 180.0f / static_cast<float>(M_PI);
}

struct Room {
  SyntheticScene rendered;
  std::vector<Eigen::Vector3f> camera_points;  // in the camera's optical frame
  Eigen::Vector3f up_in_camera;
  float floor_level_in_camera = 0;
};

// A chair and a table on a floor in front of a wall 3 m away, from a camera at `eye`, in the
// camera's own frame: what a robot's Kinect sends.
Room renderRoom(const Eigen::Vector3f& eye, const Eigen::Vector3f& target, bool floor = true) {
  std::vector<SceneObject> objects;
  objects.push_back({"office_chair", testing::syntheticFurniture("office_chair", 0), -0.4f, 0.2f, 0.3f});
  objects.push_back({"dining_table", testing::syntheticFurniture("dining_table", 0), 0.6f, 0.6f, 0.0f});
  objects.push_back({"wall", testing::boxMesh({-3, 2.0f, 0}, {3, 2.1f, 2.5f}), 0, 0, 0});
  SyntheticSceneParams params;
  params.camera_eye = eye;
  params.camera_target = target;
  params.floor_size = floor ? 8.0f : 0.0f;
  Room room;
  room.rendered = composeScene(objects, params);
  const Eigen::Isometry3f world_to_camera = room.rendered.depth.camera_to_world.inverse();
  for (const auto& p : *room.rendered.scene.cloud) room.camera_points.push_back(world_to_camera * p.getVector3fMap());
  room.up_in_camera = world_to_camera.linear() * Eigen::Vector3f::UnitZ();
  // The floor z = 0 in camera coordinates: up_c . p_c = up_c . (R p_w + t) = z_w + up_c . t.
  room.floor_level_in_camera = room.up_in_camera.dot(world_to_camera.translation());
  return room;
}

TEST(Gravity, FindsTheFloorFromATiltedCameraAndLabelsFloorAndWall) {
  for (const auto& [eye, target] : {std::pair{Eigen::Vector3f(0, -2.5f, 1.2f), Eigen::Vector3f(0, 0.5f, 0.4f)},
                                    std::pair{Eigen::Vector3f(0.5f, -2.0f, 1.6f), Eigen::Vector3f(0.2f, 0.5f, 0.2f)},
                                    std::pair{Eigen::Vector3f(-1.0f, -2.2f, 0.6f), Eigen::Vector3f(0.0f, 1.0f, 0.6f)}}) {
    const Room room = renderRoom(eye, target);
    const GravityResult r = estimateGravity(room.camera_points, Eigen::Vector3f::Zero(), {0, -1, 0}, std::nullopt);
    EXPECT_EQ(r.gravity.source, UpSource::kFloor);
    EXPECT_LT(degreesBetween(r.gravity.up, room.up_in_camera), 1.5f) << eye.transpose();
    ASSERT_TRUE(r.gravity.hasFloor());
    EXPECT_NEAR(*r.gravity.floor_level, room.floor_level_in_camera, 0.02f);
    EXPECT_EQ(r.gravity.walls, 1);
    // Every point of an object is free; floor and wall points are labelled.
    size_t object_points = 0, object_labelled = 0, floor_hits = 0, floor_points = 0;
    for (size_t i = 0; i < room.camera_points.size(); ++i) {
      const int object = room.rendered.point_object[i];
      if (object < 0) {
        ++floor_points;
        floor_hits += r.labels[i] == PlaneLabel::kFloor;
      } else if (object < 2) {
        ++object_points;
        object_labelled += r.labels[i] != PlaneLabel::kNone && r.gravity.height(room.camera_points[i]) > 0.05f;
      }
    }
    EXPECT_GT(floor_hits, floor_points * 95 / 100);
    EXPECT_LT(object_labelled, object_points / 100);
  }
}

TEST(Gravity, AGivenUpIsKeptAndTheFloorLevelFound) {
  const Room room = renderRoom({0, -2.5f, 1.2f}, {0, 0.5f, 0.4f});
  const GravityResult r = estimateGravity(room.camera_points, Eigen::Vector3f::Zero(), {0, -1, 0}, room.up_in_camera * 2.0f);
  EXPECT_EQ(r.gravity.source, UpSource::kGiven);
  EXPECT_LT(degreesBetween(r.gravity.up, room.up_in_camera), 1e-3f);
  ASSERT_TRUE(r.gravity.hasFloor());
  EXPECT_NEAR(*r.gravity.floor_level, room.floor_level_in_camera, 0.02f);
  EXPECT_THROW(estimateGravity(room.camera_points, Eigen::Vector3f::Zero(), {0, -1, 0}, Eigen::Vector3f::Zero()), Error);
  EXPECT_THROW(estimateGravity(room.camera_points, Eigen::Vector3f::Zero(), {0, -1, 0}, Eigen::Vector3f(NAN, 0, 1)), Error);
}

TEST(Gravity, WithoutAFloorTheSensorsUpIsAssumedAndATableTopIsNoFloor) {
  // No floor rendered: the table top is the largest horizontal plane, but chair legs and the wall
  // reach below it.
  const Room room = renderRoom({0, -2.5f, 1.2f}, {0, 0.5f, 0.4f}, /*floor=*/false);
  const Eigen::Vector3f sensor_up{0, -1, 0};
  const GravityResult r = estimateGravity(room.camera_points, Eigen::Vector3f::Zero(), sensor_up, std::nullopt);
  EXPECT_EQ(r.gravity.source, UpSource::kAssumed);
  EXPECT_FALSE(r.gravity.hasFloor());
  EXPECT_TRUE(r.gravity.up.isApprox(sensor_up));
  EXPECT_EQ(r.gravity.floor_points, 0u);
}

// A fused room whose floor holds 4 % of the points, the rest walls and clutter, tilted 0.5 degree
// from the up it is written with: three random points seldom all fall on the floor, one does.
TEST(Gravity, ASmallFloorNearlySquareToThePriorIsFoundAndItsOwnNormalTaken) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-3.0f, 3.0f), h(0.05f, 2.5f);
  const Eigen::Matrix3f tilt = Eigen::AngleAxisf(0.0087f, Eigen::Vector3f::UnitX()).toRotationMatrix();
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < 800; ++i) points.push_back(tilt * Eigen::Vector3f(u(rng), u(rng), 0.0f));
  for (int i = 0; i < 19200; ++i) {  // four walls and things standing in the room
    const float a = u(rng), b = h(rng);
    switch (i % 5) {
      case 0: points.push_back(tilt * Eigen::Vector3f(a, 3.0f, b)); break;
      case 1: points.push_back(tilt * Eigen::Vector3f(a, -3.0f, b)); break;
      case 2: points.push_back(tilt * Eigen::Vector3f(3.0f, a, b)); break;
      case 3: points.push_back(tilt * Eigen::Vector3f(-3.0f, a, b)); break;
      default: points.push_back(tilt * Eigen::Vector3f(0.5f * a, u(rng), b)); break;
    }
  }
  GravityParams params;
  params.prior_iterations = 0;  // three-point planes only
  EXPECT_FALSE(estimateGravity(points, Eigen::Vector3f(0, 0, 1.5f), Eigen::Vector3f::UnitZ(), std::nullopt, params)
                   .gravity.hasFloor());
  const Gravity g = estimateGravity(points, Eigen::Vector3f(0, 0, 1.5f), Eigen::Vector3f::UnitZ(), std::nullopt).gravity;
  ASSERT_TRUE(g.hasFloor());
  EXPECT_EQ(g.source, UpSource::kFloor);
  EXPECT_LT(degreesBetween(g.up, tilt * Eigen::Vector3f::UnitZ()), 0.2f);
  EXPECT_NEAR(*g.floor_level, 0.0f, 0.01f);
}

TEST(Gravity, TheHandLevelledFloorOfARealKinectFrame) {
  const std::string dir = std::string(ISM_SHARED_DATA_DIR) + "/real/kinect/";
  if (!std::filesystem::exists(dir + "tum_desk.json")) GTEST_SKIP() << "shared data not present: " << dir;
  const nlohmann::json truth = nlohmann::json::parse(std::ifstream(dir + "tum_desk.json"));
  const Eigen::Vector3f normal(truth["floor_normal"][0].get<float>(), truth["floor_normal"][1].get<float>(),
                               truth["floor_normal"][2].get<float>());
  const float level = -truth["floor_d"].get<float>();  // n . p + d = 0
  const Scene scene = loadCloudFile(dir + "tum_desk.pcd");
  const auto cloud = downsample(*scene.cloud, {});
  std::vector<Eigen::Vector3f> points;
  for (const auto& p : *cloud) points.push_back(p.getVector3fMap());
  const GravityResult r = estimateGravity(points, Eigen::Vector3f::Zero(), {0, -1, 0}, std::nullopt);
  EXPECT_EQ(r.gravity.source, UpSource::kFloor);
  EXPECT_LT(degreesBetween(r.gravity.up, normal), 2.0f);
  ASSERT_TRUE(r.gravity.hasFloor());
  // Where the floor was seen (the centroid of the points taken for it), the two planes agree.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < points.size(); ++i) {
    if (r.labels[i] == PlaneLabel::kFloor) centroid += points[i].cast<double>();
  }
  ASSERT_GT(r.gravity.floor_points, 10000u);
  const Eigen::Vector3f middle = (centroid / static_cast<double>(r.gravity.floor_points)).cast<float>();
  EXPECT_NEAR(r.gravity.height(middle), normal.dot(middle) - level, 0.03f);
}

}  // namespace
}  // namespace ism
