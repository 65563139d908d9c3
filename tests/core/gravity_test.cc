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

// A caller's up a degree or two off is kept; one farther off the floor's normal than
// given_up_kept_deg gives way to it, unless the caller's up is to be trusted.
TEST(Gravity, AGivenUpTiltedFarFromTheFloorGivesWayToTheFloor) {
  const Room room = renderRoom({0, -2.5f, 1.2f}, {0, 0.5f, 0.4f});
  // Tilted about the camera's x axis, square to up: the given up leans towards or away from the
  // camera.
  const auto tilted = [&](float degrees) {
    const Eigen::Vector3f axis = room.up_in_camera.cross(Eigen::Vector3f::UnitZ()).normalized();
    return Eigen::Vector3f(Eigen::AngleAxisf(degrees * static_cast<float>(M_PI) / 180.0f, axis) * room.up_in_camera);
  };
  GravityParams params;
  ASSERT_EQ(params.given_up_kept_deg, 3.0f);
  for (const float degrees : {-1.5f, 1.5f}) {
    const GravityResult r = estimateGravity(room.camera_points, Eigen::Vector3f::Zero(), {0, -1, 0}, tilted(degrees), params);
    EXPECT_EQ(r.gravity.source, UpSource::kGiven) << degrees;
    EXPECT_LT(degreesBetween(r.gravity.up, tilted(degrees)), 1e-3f) << degrees;
    EXPECT_TRUE(r.gravity.hasFloor()) << degrees;
  }
  for (const float degrees : {-7.0f, 7.0f}) {
    const GravityResult r = estimateGravity(room.camera_points, Eigen::Vector3f::Zero(), {0, -1, 0}, tilted(degrees), params);
    EXPECT_EQ(r.gravity.source, UpSource::kFloor) << degrees;
    EXPECT_LT(degreesBetween(r.gravity.up, room.up_in_camera), 0.5f) << degrees;
    ASSERT_TRUE(r.gravity.hasFloor()) << degrees;
    EXPECT_NEAR(*r.gravity.floor_level, room.floor_level_in_camera, 0.02f) << degrees;
  }
  // Trusted (as ism-detect --trust-given-up): never second-guessed.
  params.given_up_kept_deg = params.given_up_tolerance_deg;
  const GravityResult r = estimateGravity(room.camera_points, Eigen::Vector3f::Zero(), {0, -1, 0}, tilted(7.0f), params);
  EXPECT_EQ(r.gravity.source, UpSource::kGiven);
  EXPECT_LT(degreesBetween(r.gravity.up, tilted(7.0f)), 1e-3f);
  // Beyond the tolerance the floor is not searched for: the given up stays, floor or none.
  params.given_up_kept_deg = 3.0f;
  const GravityResult far = estimateGravity(room.camera_points, Eigen::Vector3f::Zero(), {0, -1, 0}, tilted(20.0f), params);
  EXPECT_EQ(far.gravity.source, UpSource::kGiven);
  EXPECT_LT(degreesBetween(far.gravity.up, tilted(20.0f)), 1e-3f);
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

// Points on a grid of `spacing` over the rectangle from `corner` along `a` and `b` (lengths of
// the vectors), as a dense sensor sees a flat face.
void addFace(std::vector<Eigen::Vector3f>& points, const Eigen::Vector3f& corner, const Eigen::Vector3f& a,
             const Eigen::Vector3f& b, float spacing) {
  for (float s = 0; s <= a.norm(); s += spacing) {
    for (float t = 0; t <= b.norm(); t += spacing) points.push_back(corner + a.normalized() * s + b.normalized() * t);
  }
}

TEST(Gravity, WithWallCellsFacesThatOnlyShareAPlaneAreNoWall) {
  // A floor, a wall 3 m away, and three cabinets 1.2 m high, 0.4 m wide and 0.8 m apart whose
  // fronts lie on one vertical plane: together they span 2 m along it and 1.2 m up, as a wall's
  // points do, but each alone is far narrower than a wall. Dense, as a Kinect frame is (3 cm).
  std::vector<Eigen::Vector3f> points;
  addFace(points, {-3, -3, 0}, {6, 0, 0}, {0, 6, 0}, 0.03f);
  addFace(points, {-3, 3, 0}, {6, 0, 0}, {0, 0, 2.5f}, 0.03f);
  const size_t before_cabinets = points.size();
  for (float x : {-1.0f, 0.2f, 1.4f}) {
    addFace(points, {x - 0.8f, -0.2f, 0.02f}, {0.4f, 0, 0}, {0, 0, 1.2f}, 0.03f);  // the front, at y = -0.2
    addFace(points, {x - 0.8f, -0.2f, 1.2f}, {0.4f, 0, 0}, {0, 0.4f, 0}, 0.03f);   // the top
    addFace(points, {x - 0.8f, -0.2f, 0.02f}, {0, 0.4f, 0}, {0, 0, 1.2f}, 0.03f);  // a side
  }
  GravityParams params;
  params.wall_cell = 0.15f;
  const GravityResult r =
      estimateGravity(points, Eigen::Vector3f(0, -4, 1.5f), Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitZ(), params);
  ASSERT_TRUE(r.gravity.hasFloor());
  EXPECT_EQ(r.gravity.walls, 1);
  size_t wall = 0, wall_labelled = 0, cabinets = 0, cabinets_labelled = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    if (points[i].z() < 0.3f) continue;  // the floor's band: 2.5 sigma of the depth noise at 7 m is 21 cm
    if (i < before_cabinets) {
      ++wall;
      wall_labelled += r.labels[i] == PlaneLabel::kWall;
    } else {
      ++cabinets;
      cabinets_labelled += r.labels[i] == PlaneLabel::kWall;
    }
  }
  EXPECT_GT(wall_labelled, wall * 95 / 100);
  EXPECT_EQ(cabinets_labelled, 0u) << "of " << cabinets;
  // Without the cells (the default), the plane through the cabinets' fronts is a second wall.
  const GravityResult planes =
      estimateGravity(points, Eigen::Vector3f(0, -4, 1.5f), Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitZ());
  EXPECT_EQ(planes.gravity.walls, 2);
}

TEST(Gravity, WithWallCellsASparselySampledWallIsStillAWall) {
  // A fused apartment sampled to 50,000 points holds about 35 points per square metre of wall,
  // too few per 15 cm cell to show a surface: the wall is then the extent of its points.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> x(-2.0f, 2.0f), z(0.0f, 2.5f);
  std::vector<Eigen::Vector3f> points;
  addFace(points, {-3, -3, 0}, {6, 0, 0}, {0, 6, 0}, 0.1f);
  const size_t floor = points.size();
  for (int i = 0; i < 350; ++i) points.push_back({x(rng), 2.0f, z(rng)});
  GravityParams params;
  params.wall_cell = 0.15f;
  const GravityResult r =
      estimateGravity(points, Eigen::Vector3f(0, -2, 1.5f), Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitZ(), params);
  EXPECT_EQ(r.gravity.walls, 1);
  size_t labelled = 0, wall = 0;
  for (size_t i = floor; i < points.size(); ++i) {
    if (points[i].z() < 0.05f) continue;
    ++wall;
    labelled += r.labels[i] == PlaneLabel::kWall;
  }
  EXPECT_GT(labelled, wall * 95 / 100);
}

// A floor and, 3 m from a camera at 1.5 m, a wall 6 m wide and 2.5 m high, at 3 cm as a dense
// frame shows them.
std::vector<Eigen::Vector3f> floorAndWall() {
  std::vector<Eigen::Vector3f> points;
  addFace(points, {-3, -4, 0}, {6, 0, 0}, {0, 7, 0}, 0.03f);
  addFace(points, {-3, 3, 0}, {6, 0, 0}, {0, 0, 2.5f}, 0.03f);
  return points;
}

size_t labelledWall(const GravityResult& r, size_t from, size_t to) {
  size_t n = 0;
  for (size_t i = from; i < to; ++i) n += r.labels[i] == PlaneLabel::kWall;
  return n;
}

TEST(Gravity, APlaneTheRoomIsSeenThroughIsNoWall) {
  // Five boards 10 cm wide and 1.1 m high stand in line 0.6 m apart, as a desk's legs and front,
  // chairs' backs and a cabinet's side do in tum_desk: together they span a wall's width and
  // height on one vertical plane, and the wall behind shows between them.
  std::vector<Eigen::Vector3f> points = floorAndWall();
  const size_t before_boards = points.size();
  for (float x : {-1.2f, -0.6f, 0.0f, 0.6f, 1.2f}) addFace(points, {x - 0.05f, 0.5f, 0.05f}, {0.1f, 0, 0}, {0, 0, 1.1f}, 0.03f);
  const Eigen::Vector3f camera(0, -3, 1.5f);
  GravityParams params;
  params.wall_max_seen_through = 1.0f;
  const GravityResult r = estimateGravity(points, camera, Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitZ(), params);
  EXPECT_EQ(r.gravity.walls, 1);
  EXPECT_EQ(labelledWall(r, before_boards, points.size()), 0u);
  size_t wall = 0;
  for (size_t i = 0; i < before_boards; ++i) wall += points[i].y() > 2.9f && points[i].z() > 0.3f;
  EXPECT_GT(labelledWall(r, 0, before_boards), wall * 95 / 100);
  // Without the limit, the boards' plane is a wall too.
  params.wall_max_seen_through = 0.0f;
  const GravityResult planes = estimateGravity(points, camera, Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitZ(), params);
  EXPECT_EQ(planes.gravity.walls, 2);
  EXPECT_GT(labelledWall(planes, before_boards, points.size()), (points.size() - before_boards) / 2);
}

TEST(Gravity, AWallWithADoorwayIsStillAWall) {
  // The room behind a doorway 1 m wide and 2 m high is seen through the wall, and the wall stays
  // one: far fewer points are seen through it than it has. The camera looks at it from the side,
  // a map's viewpoint in the middle of the room would too.
  std::vector<Eigen::Vector3f> points;
  addFace(points, {-3, -4, 0}, {6, 0, 0}, {0, 9, 0}, 0.03f);
  const size_t before_wall = points.size();
  addFace(points, {-3, 3, 0}, {2.5f, 0, 0}, {0, 0, 2.5f}, 0.03f);
  addFace(points, {0.5f, 3, 0}, {2.5f, 0, 0}, {0, 0, 2.5f}, 0.03f);
  addFace(points, {-0.5f, 3, 2.0f}, {1.0f, 0, 0}, {0, 0, 0.5f}, 0.03f);
  const size_t wall_end = points.size();
  addFace(points, {-1.5f, 5, 0}, {3.0f, 0, 0}, {0, 0, 2.5f}, 0.03f);  // the next room's wall, seen through the door
  GravityParams params;
  params.wall_max_seen_through = 1.0f;
  const GravityResult r =
      estimateGravity(points, Eigen::Vector3f(1.0f, -2, 1.5f), Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitZ(), params);
  ASSERT_GE(r.gravity.walls, 1);
  EXPECT_GT(labelledWall(r, before_wall, wall_end), (wall_end - before_wall) * 9 / 10);
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
