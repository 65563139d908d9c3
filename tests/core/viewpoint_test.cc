#include "core/gravity/viewpoint.h"

#include <gtest/gtest.h>

#include <cmath>

namespace ism {
namespace {

// A room 6 x 4 m, 2.5 m high, z up, its frame's origin on the floor in the middle (as ScanNet's
// rooms are): floor and four walls, 5 cm apart.
Scene room() {
  Scene s;
  s.source = "room";
  const auto add = [&](float x, float y, float z) { s.cloud->push_back(PointT(x, y, z)); };
  for (float x = -3.0f; x <= 3.0f; x += 0.05f) {
    for (float y = -2.0f; y <= 2.0f; y += 0.05f) add(x + 0.5f, y, 0.0f);
    for (float z = 0.0f; z <= 2.5f; z += 0.05f) add(x + 0.5f, -2.0f, z), add(x + 0.5f, 2.0f, z);
  }
  for (float y = -2.0f; y <= 2.0f; y += 0.05f) {
    for (float z = 0.0f; z <= 2.5f; z += 0.05f) add(-2.5f, y, z), add(3.5f, y, z);
  }
  return s;
}

// What a depth camera at the origin sees along +z: points within its 57 x 43 degree view.
Scene frame() {
  Scene s;
  s.source = "frame";
  for (float u = -0.5f; u <= 0.5f; u += 0.02f) {
    for (float v = -0.38f; v <= 0.38f; v += 0.02f) s.cloud->push_back(PointT(3.0f * u, 3.0f * v, 3.0f));
  }
  return s;
}

TEST(MapViewpoint, AMapIsSeenFromItsMiddleAtEyeHeight) {
  Scene s = room();
  s.up = Eigen::Vector3f(0, 0, 2);  // any length
  const auto view = mapViewpoint(s);
  ASSERT_TRUE(view.has_value());
  const Eigen::Vector3f& viewpoint = view->origin;
  EXPECT_NEAR((view->up - Eigen::Vector3f::UnitZ()).norm(), 0.0f, 1e-6f);
  // The centroid across up lies inside the room, near its middle (walls weigh it); the height is
  // the floor's plus 1.5 m.
  EXPECT_NEAR(viewpoint.x(), 0.5f, 0.3f);
  EXPECT_NEAR(viewpoint.y(), 0.0f, 0.1f);
  EXPECT_NEAR(viewpoint.z(), 1.5f, 1e-3f);
  ViewpointParams low;
  low.eye_height = 0.5f;
  EXPECT_NEAR(mapViewpoint(s, low)->origin.z(), 0.5f, 1e-3f);
}

TEST(MapViewpoint, ASingleViewKeepsItsOrigin) {
  EXPECT_FALSE(mapViewpoint(frame()).has_value());
  // Turned anywhere: the view's own cone decides, not an axis.
  Scene turned = frame();
  for (auto& p : turned.cloud->points) p.getVector3fMap() = Eigen::Vector3f(p.z, -p.x, p.y);
  EXPECT_FALSE(mapViewpoint(turned).has_value());
}

TEST(Surrounds, AMapAroundAnyViewpointAViewFromItsOwn) {
  EXPECT_TRUE(surrounds(*room().cloud, Eigen::Vector3f::Zero()));
  EXPECT_TRUE(surrounds(*room().cloud, Eigen::Vector3f(0.5f, 0.0f, 1.5f)));  // a map's made-up viewpoint
  EXPECT_FALSE(surrounds(*frame().cloud, Eigen::Vector3f::Zero()));
  // The same view taken from far behind its sensor still lies in one cone.
  EXPECT_FALSE(surrounds(*frame().cloud, Eigen::Vector3f(0.0f, 0.0f, -2.0f)));
  // From inside the view's own points, they lie all around.
  EXPECT_TRUE(surrounds(*frame().cloud, Eigen::Vector3f(0.0f, 0.0f, 3.0f)));
  EXPECT_FALSE(surrounds(Cloud(), Eigen::Vector3f::Zero()));
}

TEST(MapViewpoint, AScenesOwnPoseOrImageGridStands) {
  Scene posed = room();
  posed.sensor_origin = Eigen::Vector3f(0.5f, 0, 1.2f);
  EXPECT_FALSE(mapViewpoint(posed).has_value());
  Scene turned = room();
  turned.sensor_orientation = Eigen::Quaternionf(Eigen::AngleAxisf(0.3f, Eigen::Vector3f::UnitZ()));
  EXPECT_FALSE(mapViewpoint(turned).has_value());
  Scene organized = room();
  organized.image_width = 1;
  organized.image_height = static_cast<int>(organized.cloud->size());
  EXPECT_FALSE(mapViewpoint(organized).has_value());
  EXPECT_FALSE(mapViewpoint(Scene{}).has_value());
}

// The room written in each convention maps come in: its floor, the largest layer, gives up.
TEST(MapUp, TheAxisWhoseLowestLayerHoldsTheFloor) {
  const Scene z_up = room();
  EXPECT_EQ(mapUp(*z_up.cloud), Eigen::Vector3f(0, 0, 1));
  Scene y_down = room(), y_up = room();
  for (auto& p : y_down.cloud->points) p.getVector3fMap() = Eigen::Vector3f(p.x, -p.z, p.y);
  for (auto& p : y_up.cloud->points) p.getVector3fMap() = Eigen::Vector3f(p.x, p.z, -p.y);
  EXPECT_EQ(mapUp(*y_down.cloud), Eigen::Vector3f(0, -1, 0));
  EXPECT_EQ(mapUp(*y_up.cloud), Eigen::Vector3f(0, 1, 0));
}

TEST(LookedAt, AMapWithoutUpIsTurnedSoThatTheFloorIsSoughtBelow) {
  const Scene seen = lookedAt(room());
  EXPECT_NEAR(seen.sensor_origin.z(), 1.5f, 1e-3f);
  const Eigen::Vector3f sensor_up = seen.sensor_orientation * Eigen::Vector3f(0, -1, 0);
  EXPECT_NEAR((sensor_up - Eigen::Vector3f::UnitZ()).norm(), 0.0f, 1e-5f);
  Scene given = room();
  given.up = Eigen::Vector3f::UnitZ();
  EXPECT_TRUE(lookedAt(given).sensor_orientation.isApprox(Eigen::Quaternionf::Identity()));
  const Scene single = frame();
  EXPECT_EQ(lookedAt(single).sensor_origin, Eigen::Vector3f::Zero());
}

TEST(LookedAt, AnImageWhosePoseTurnsItsSensorAwayIsTakenInItsPointsOwnFrame) {
  // A depth image in the optical frame (z forward), its pose turned 180 degrees about x (w 0,
  // x 1), as PCL's test frames carry it: its -y, the floor's side, would point down.
  Scene image = frame();
  image.image_width = 26;
  image.image_height = 20;
  const Eigen::Quaternionf away(0, 1, 0, 0);
  image.sensor_orientation = away;
  EXPECT_FALSE(facesItsPoints(image));
  EXPECT_TRUE(lookedAt(image).sensor_orientation.isApprox(Eigen::Quaternionf::Identity()));
  // The same pose with the points where it looks (z negated) stands.
  Scene turned = image;
  turned.cloud.reset(new Cloud);
  for (const auto& p : image.cloud->points) turned.cloud->push_back(PointT(p.x, -p.y, -p.z));
  EXPECT_TRUE(facesItsPoints(turned));
  EXPECT_TRUE(lookedAt(turned).sensor_orientation.isApprox(away));
  // A cloud without an image grid keeps its pose: a room sample's frame need not be optical.
  Scene cloud = image;
  cloud.image_width = cloud.image_height = 0;
  EXPECT_TRUE(lookedAt(cloud).sensor_orientation.isApprox(away));
}

// A single view 1.2 m above a floor, looking along `forward` (z up and y forward in SUN RGB-D's
// frames; y down and z forward in a camera's optical frame): floor from 1 to 4 m ahead, a wall
// across the line of sight at 4 m, denser than any layer of the floor.
Scene singleView(bool optical) {
  Scene s;
  const auto add = [&](float x, float ahead, float height) {
    s.cloud->push_back(optical ? PointT(x, 1.2f - height, ahead) : PointT(x, ahead, height - 1.2f));
  };
  for (float x = -1.5f; x <= 1.5f; x += 0.05f) {
    for (float ahead = 1.0f; ahead < 4.0f; ahead += 0.05f) add(x, ahead, 0.0f);
    for (float height = 0.0f; height <= 2.5f; height += 0.02f) add(x, 4.0f, height);
  }
  return s;
}

TEST(LookedAt, ASingleViewWithoutPoseOrUpSeeksItsFloorAcrossItsLineOfSight) {
  const Eigen::Vector3f sun_up = lookedAt(singleView(false)).sensor_orientation * Eigen::Vector3f(0, -1, 0);
  EXPECT_NEAR((sun_up - Eigen::Vector3f::UnitZ()).norm(), 0.0f, 1e-5f);
  const Eigen::Vector3f optical_up = lookedAt(singleView(true)).sensor_orientation * Eigen::Vector3f(0, -1, 0);
  EXPECT_NEAR((optical_up - Eigen::Vector3f(0, -1, 0)).norm(), 0.0f, 1e-5f);
  // Without the line of sight, the wall's layer would have won.
  EXPECT_NEAR((mapUp(*singleView(false).cloud) - Eigen::Vector3f(0, -1, 0)).norm(), 0.0f, 1e-5f);
  // A given up or pose stands.
  Scene given = singleView(false);
  given.up = Eigen::Vector3f::UnitZ();
  EXPECT_TRUE(lookedAt(given).sensor_orientation.isApprox(Eigen::Quaternionf::Identity()));
}

TEST(RoomCentreViewpoint, UpNeedNotBeAnAxis) {
  Scene s = room();
  const Eigen::Matrix3f tilt = Eigen::AngleAxisf(0.4f, Eigen::Vector3f::UnitX()).toRotationMatrix();
  for (auto& p : s.cloud->points) p.getVector3fMap() = tilt * p.getVector3fMap();
  const Eigen::Vector3f up = tilt * Eigen::Vector3f::UnitZ();
  const Eigen::Vector3f v = roomCentreViewpoint(*s.cloud, up, 1.5f);
  EXPECT_NEAR(up.dot(v), 1.5f, 1e-3f);  // the floor is at 0 along up
}

}  // namespace
}  // namespace ism
