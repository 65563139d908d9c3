// Upright boxes: the overlap measure of 3D detection (footprint polygons times height overlap),
// and turning oriented boxes of any scene frame into upright boxes of its gravity frame.
#include "core/common/upright_box.h"

#include <gtest/gtest.h>

#include <cmath>

namespace ism {
namespace {

UprightBox box(Eigen::Vector3f center, Eigen::Vector3f size, float yaw = 0) { return {center, size, yaw}; }

TEST(UprightBox, IouOfBoxesThatShareOrOverlapVolume) {
  const UprightBox unit = box({0, 0, 0.5f}, {1, 1, 1});
  EXPECT_NEAR(intersectionOverUnion(unit, unit), 1.0f, 1e-6f);
  // Shifted by half along x: half of each overlaps, IoU = 0.5 / 1.5.
  EXPECT_NEAR(intersectionOverUnion(unit, box({0.5f, 0, 0.5f}, {1, 1, 1})), 1.0f / 3, 1e-5f);
  // Shifted by half in height only: the same.
  EXPECT_NEAR(intersectionOverUnion(unit, box({0, 0, 1.0f}, {1, 1, 1})), 1.0f / 3, 1e-5f);
  // Apart: nothing, also when they only touch.
  EXPECT_EQ(intersectionOverUnion(unit, box({1, 0, 0.5f}, {1, 1, 1})), 0.0f);
  EXPECT_EQ(intersectionOverUnion(unit, box({3, 3, 0.5f}, {1, 1, 1})), 0.0f);
  // A degenerate box overlaps nothing.
  EXPECT_EQ(intersectionOverUnion(unit, box({0, 0, 0.5f}, {1, 0, 1})), 0.0f);
}

// Two unit squares turned by 45 degrees reach 0.7071 m along x from their centres: 1.41 m apart,
// their corners overlap in a small square of diagonal 0.0042 m (8.9e-6 m^2), which counts
// however near the boxes' reach it lies.
TEST(UprightBox, IouOfCornersOverlappingAtTheBoxesReach) {
  const float turn = static_cast<float>(M_PI / 4);
  const UprightBox a = box({0, 0, 0.5f}, {1, 1, 1}, turn);
  const float diagonal = std::sqrt(2.0f) - 1.41f;
  EXPECT_NEAR(intersectionOverUnion(a, box({1.41f, 0, 0.5f}, {1, 1, 1}, turn)),
              diagonal * diagonal / 2 / (2 - diagonal * diagonal / 2), 1e-7f);
  EXPECT_EQ(intersectionOverUnion(a, box({1.42f, 0, 0.5f}, {1, 1, 1}, turn)), 0.0f);
  EXPECT_EQ(intersectionOverUnion(a, box({1.0f, 1.0f, 0.5f}, {1, 1, 1}, turn)), 0.0f) << "edge to edge";
}

TEST(UprightBox, IouFollowsYaw) {
  const UprightBox square = box({0, 0, 0.5f}, {1, 1, 1});
  // A unit square turned by 45 degrees meets the original in an octagon of area 2 (sqrt 2 - 1).
  const float octagon = 2 * (std::sqrt(2.0f) - 1);
  EXPECT_NEAR(intersectionOverUnion(square, box({0, 0, 0.5f}, {1, 1, 1}, static_cast<float>(M_PI / 4))),
              octagon / (2 - octagon), 1e-5f);
  // A 2 x 0.5 plank turned by 90 degrees is the same plank only in the middle: 0.25 of 1 + 1.
  const UprightBox plank = box({0, 0, 0.5f}, {2, 0.5f, 1});
  EXPECT_NEAR(intersectionOverUnion(plank, box({0, 0, 0.5f}, {2, 0.5f, 1}, static_cast<float>(M_PI / 2))),
              0.25f / 1.75f, 1e-5f);
  // Turned by 180 degrees a box is itself.
  EXPECT_NEAR(intersectionOverUnion(plank, box({0, 0, 0.5f}, {2, 0.5f, 1}, static_cast<float>(M_PI))), 1.0f, 1e-5f);
}

// A 2 x 0.5 plank at (1, 1) turned by 90 degrees covers x in [0.75, 1.25] and y in [0, 2], at any height.
TEST(UprightBox, FootprintFollowsYaw) {
  const UprightBox plank = box({1, 1, 0.5f}, {2, 0.5f, 1}, static_cast<float>(M_PI / 2));
  EXPECT_TRUE(insideFootprint({1, 1.9f, 0.5f}, plank));
  EXPECT_TRUE(insideFootprint({1.2f, 0.1f, 7}, plank)) << "above the box: its footprint still";
  EXPECT_FALSE(insideFootprint({1.9f, 1, 0.5f}, plank)) << "along the unturned plank's length";
  EXPECT_FALSE(insideFootprint({1, 2.1f, 0.5f}, plank));
}

TEST(UprightBox, GravityRotationPutsUpOnZ) {
  for (const Eigen::Vector3f up : {Eigen::Vector3f(0, 0, 1), Eigen::Vector3f(0.01f, -0.88f, -0.47f),
                                   Eigen::Vector3f(1, 0, 0), Eigen::Vector3f(0, -1, 0)}) {
    const Eigen::Matrix3f r = gravityRotation(up);
    EXPECT_TRUE((r * up.normalized()).isApprox(Eigen::Vector3f::UnitZ(), 1e-5f)) << up.transpose();
    EXPECT_TRUE((r * r.transpose()).isIdentity(1e-5f));
    EXPECT_NEAR(r.determinant(), 1.0f, 1e-5f);
  }
  EXPECT_TRUE(gravityRotation({0, 0, 1}).isIdentity(1e-6f));
}

TEST(UprightBox, OrientedBoxesOfAnyFrameBecomeUprightBoxes) {
  // A camera frame (y down, z forward) tilted by 30 degrees about x: its up is -y turned.
  const Eigen::Matrix3f camera_to_world =
      Eigen::AngleAxisf(static_cast<float>(-M_PI / 2 - M_PI / 6), Eigen::Vector3f::UnitX()).toRotationMatrix();
  const Eigen::Vector3f up_in_camera = camera_to_world.transpose() * Eigen::Vector3f::UnitZ();
  const Eigen::Matrix3f to_gravity = gravityRotation(up_in_camera);
  // A chair box standing upright in the world, yawed by 0.3, seen from that camera.
  const UprightBox truth = box({0.5f, 2.0f, 0.45f}, {0.5f, 0.6f, 0.9f}, 0.3f);
  const OrientedBox in_camera = truth.toScene(to_gravity);
  const UprightBox back = uprightBoxOf(in_camera, to_gravity);
  EXPECT_TRUE(back.center.isApprox(truth.center, 1e-5f));
  EXPECT_NEAR(intersectionOverUnion(back, truth), 1.0f, 1e-4f);

  // A box lying on its side (its x axis vertical) becomes the upright box of its corners.
  OrientedBox lying;
  lying.size = {0.9f, 0.5f, 0.6f};
  lying.rotation = Eigen::Quaternionf(Eigen::AngleAxisf(static_cast<float>(M_PI / 2), Eigen::Vector3f::UnitY()));
  const UprightBox upright = uprightBoxOf(lying, Eigen::Matrix3f::Identity());
  EXPECT_NEAR(upright.size.z(), 0.9f, 1e-5f);
  EXPECT_NEAR(upright.volume(), lying.volume(), 1e-5f);

  // A tilted box gets the tightest upright box: larger than itself, and holding it.
  OrientedBox tilted;
  tilted.size = {1, 1, 1};
  tilted.rotation = Eigen::Quaternionf(Eigen::AngleAxisf(0.3f, Eigen::Vector3f::UnitX()));
  const UprightBox around = uprightBoxOf(tilted, Eigen::Matrix3f::Identity());
  EXPECT_GT(around.volume(), 1.0f);
  EXPECT_NEAR(around.size.x(), 1.0f, 1e-5f);
  EXPECT_NEAR(around.size.z(), std::cos(0.3f) + std::sin(0.3f), 1e-5f);
}

}  // namespace
}  // namespace ism
