#pragma once
// Scenes with known answers for the front-end stages: a regular plane, a wavy sheet with
// scattered points, a small depth image of a box in front of a wall, and a Kinect rendering of a
// box on a floor before a wall (the virtual scanner, with sensor noise).
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/io/cloud_io.h"
#include "core/scanner/scanner.h"
#include "tests/common/synthetic_furniture.h"

namespace ism::testing {

// n x n points with `spacing` on the plane z = `z`, centred on the z axis; row-major, so the
// point (i, j) is at index i * n + j.
inline XyzCloud gridPlane(int n, float spacing, float z) {
  XyzCloud cloud;
  const float half = (n - 1) * spacing / 2;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) cloud.push_back(pcl::PointXYZ(j * spacing - half, i * spacing - half, z));
  }
  return cloud;
}

inline std::vector<Eigen::Vector3f> randomSurfacePoints(size_t n, unsigned seed) {
  // A wavy sheet plus scattered points: clustered cells and nearly empty ones.
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.5f, 0.5f);
  std::vector<Eigen::Vector3f> points;
  for (size_t i = 0; i < n; ++i) {
    const float x = u(rng), y = u(rng);
    points.emplace_back(x, y, i % 10 == 0 ? u(rng) : 0.1f * std::sin(6 * x) * std::cos(4 * y));
  }
  return points;
}

// A 160x120 camera (Kinect's 525 px focal length scaled to a quarter of the size) sees a box
// (front face at 1.5 m) in front of a wall at 2 m. The columns from kVoidColumn on return
// nothing (wider than ContourParams::max_gap, so not a shadow to look across), and a 3x3 hole
// sits in the wall. The box covers columns kBoxCols and rows kBoxRows (inclusive).
constexpr int kWidth = 160, kHeight = 120, kVoidColumn = 110;
constexpr int kBoxCols[2] = {62, 97}, kBoxRows[2] = {46, 73};
constexpr int kHoleCol = 20, kHoleRow = 20;

inline bool onBox(int col, int row) {
  return col >= kBoxCols[0] && col <= kBoxCols[1] && row >= kBoxRows[0] && row <= kBoxRows[1];
}

inline Scene boxInFrontOfWall() {
  DepthIntrinsics intrinsics;
  intrinsics.fx = intrinsics.fy = 131.25f;
  intrinsics.cx = 79.5f;
  intrinsics.cy = 59.5f;
  std::vector<uint16_t> depth(kWidth * kHeight);
  for (int v = 0; v < kHeight; ++v) {
    for (int u = 0; u < kWidth; ++u) {
      const bool hole = u >= kHoleCol && u < kHoleCol + 3 && v >= kHoleRow && v < kHoleRow + 3;
      depth[v * kWidth + u] = u >= kVoidColumn || hole ? 0 : onBox(u, v) ? 1500 : 2000;
    }
  }
  return depthToScene(depth.data(), kWidth, kHeight, intrinsics, "box scene");
}

// Ground truth for the Kinect-noise scene below: the box and where its silhouette is.
constexpr float kBoxHalf = 0.25f, kBoxHeight = 0.6f;

inline float distanceToBox(const Eigen::Vector3f& p) {
  const Eigen::Vector3f lo(-kBoxHalf, -kBoxHalf, 0.0f), hi(kBoxHalf, kBoxHalf, kBoxHeight);
  const Eigen::Vector3f outside = (lo - p).cwiseMax(p - hi).cwiseMax(0.0f);
  const Eigen::Vector3f inside = (p - lo).cwiseMin(hi - p);
  return outside.norm() > 0 ? outside.norm() : inside.minCoeff();
}

// A 50 x 50 x 60 cm box on a floor, a wall 1.25 m behind it, seen by a Kinect (640x480, noise
// and disparity quantisation) 3 m from the box: floor and wall fill the whole image, so the
// box's silhouette is the only depth discontinuity. Without sensor noise, every floor and wall
// point lies on its plane.
inline SyntheticScene boxOnFloorBeforeWall(bool sensor_noise = true) {
  SceneObject box{"box", boxMesh({-kBoxHalf, -kBoxHalf, 0.0f}, {kBoxHalf, kBoxHalf, kBoxHeight}), 0, 0, 0};
  SceneObject wall{"wall", boxMesh({-4.0f, 1.25f, 0.0f}, {4.0f, 1.35f, 3.0f}), 0, 0, 0};
  SyntheticSceneParams params;
  params.floor_size = 8.0f;
  // From above enough to see the top face at 24 degrees: from the default 1.2 m height it is
  // too grazing to keep a surface near its back edge after smoothing.
  params.camera_eye = {0.0f, -2.5f, 1.8f};
  params.camera_target = {0.0f, 0.0f, 0.3f};
  params.noise.enabled = sensor_noise;
  return composeScene({box, wall}, params);
}

}  // namespace ism::testing
