#include "core/frontend/frontend.h"

#include <gtest/gtest.h>
#include <pcl/features/normal_3d.h>
#include <pcl/surface/mls.h>

#ifdef _OPENMP
#include <omp.h>
#endif
#include <zlib.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <numeric>
#include <random>
#include <set>
#include <tuple>

#include "core/common/error.h"
#include "core/frontend/neighbour_grid.h"
#include "core/io/cloud_io.h"
#include "core/model/model_file.h"
#include "ism/v1/model.pb.h"
#include "core/scanner/scanner.h"
#include "tests/common/synthetic_furniture.h"
#include "tests/common/expect_error.h"

namespace ism {
namespace {

// n x n points with `spacing` on the plane z = `z`, centred on the z axis; row-major, so the
// point (i, j) is at index i * n + j.
XyzCloud gridPlane(int n, float spacing, float z) {
  XyzCloud cloud;
  const float half = (n - 1) * spacing / 2;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) cloud.push_back(pcl::PointXYZ(j * spacing - half, i * spacing - half, z));
  }
  return cloud;
}

Cloud toCloud(const XyzCloud& xyz) {
  Cloud cloud;
  for (const auto& p : xyz) {
    PointT q;
    q.x = p.x, q.y = p.y, q.z = p.z;
    cloud.push_back(q);
  }
  return cloud;
}

std::vector<Eigen::Vector3f> sortedPoints(const XyzCloud& cloud) {
  std::vector<Eigen::Vector3f> points;
  for (const auto& p : cloud) points.push_back(p.getVector3fMap());
  std::sort(points.begin(), points.end(), [](const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
  });
  return points;
}

void expectUnitDescriptorsAndRotationFrames(const Features& features) {
  ASSERT_EQ(features.descriptors.rows(), static_cast<Eigen::Index>(features.size()));
  ASSERT_EQ(features.descriptors.cols(), 352);
  ASSERT_EQ(features.lrfs.size(), features.size());
  for (size_t i = 0; i < features.size(); ++i) {
    EXPECT_NEAR(features.descriptors.row(i).norm(), 1.0f, 1e-5f) << "descriptor " << i;
    EXPECT_TRUE((features.lrfs[i] * features.lrfs[i].transpose()).isIdentity(1e-4f)) << "LRF " << i;
    EXPECT_NEAR(features.lrfs[i].determinant(), 1.0f, 1e-4f) << "LRF " << i;
  }
}

using ism::testing::expectError;

TEST(Downsample, KnownGridGivesVoxelCentroids) {
  // 8 points per axis at 2.5 mm spacing, offset by 1.25 mm: 4 per axis fall in each 1 cm voxel
  // of the 2x2x2 voxels spanning [-1 cm, 1 cm)^3, whose centroids are the voxel centres.
  Cloud cloud;
  for (int i = 0; i < 8; ++i) {
    for (int j = 0; j < 8; ++j) {
      for (int k = 0; k < 8; ++k) {
        PointT p;
        p.x = -0.00875f + 0.0025f * i, p.y = -0.00875f + 0.0025f * j, p.z = -0.00875f + 0.0025f * k;
        cloud.push_back(p);
      }
    }
  }
  DownsampleParams params;
  params.leaf_size = 0.01f;
  const auto out = downsample(cloud, params);
  ASSERT_EQ(out->size(), 8u);
  std::vector<Eigen::Vector3f> expected;
  for (float x : {-0.005f, 0.005f}) {
    for (float y : {-0.005f, 0.005f}) {
      for (float z : {-0.005f, 0.005f}) expected.emplace_back(x, y, z);
    }
  }
  for (const auto& centre : expected) {
    const auto matches = std::count_if(out->begin(), out->end(), [&](const pcl::PointXYZ& p) {
      return (p.getVector3fMap() - centre).norm() < 1e-6f;
    });
    EXPECT_EQ(matches, 1) << "voxel centre " << centre.transpose();
  }
}

TEST(Downsample, ExtentBeyondVoxelIndexRangeIsSplitExactly) {
  // Two 5 cm clusters 1.5 km apart at a 1 mm leaf: ~1e14 voxels overflow pcl::VoxelGrid's index,
  // which would silently return the input. The result must equal filtering each cluster alone.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> offset(0.0f, 0.05f);
  Cloud near_cluster, far_cluster;
  for (int i = 0; i < 2000; ++i) {
    PointT p;
    p.x = offset(rng), p.y = offset(rng), p.z = offset(rng);
    near_cluster.push_back(p);
    p.x += 1500.0f, p.y += 1500.0f;
    far_cluster.push_back(p);
  }
  DownsampleParams params;
  params.leaf_size = 0.001f;
  auto expected = *downsample(near_cluster, params);
  expected += *downsample(far_cluster, params);
  const auto got = downsample(near_cluster + far_cluster, params);
  ASSERT_LT(got->size(), near_cluster.size() + far_cluster.size());
  EXPECT_EQ(sortedPoints(*got), sortedPoints(expected));

  Cloud absurd = near_cluster;
  absurd[0].x = 1e8f;
  expectError([&] { downsample(absurd, params); }, ErrorCode::kInvalidInput, "downsample.leaf_size = 0.001");
}

TEST(Normals, PlaneNormalsFaceTheViewpoint) {
  XyzCloud cloud = gridPlane(21, 0.005f, 1.0f);
  cloud.push_back(pcl::PointXYZ(5.0f, 5.0f, 5.0f));  // isolated: no neighbours, undefined normal
  NormalParams params;
  for (float viewpoint_z : {0.0f, 3.0f}) {
    const auto surface = estimateNormals(cloud, params, Eigen::Vector3f(0.2f, -0.1f, viewpoint_z));
    ASSERT_EQ(surface->size(), cloud.size() - 1) << "the isolated point must be dropped";
    const float expected_z = viewpoint_z < 1.0f ? -1.0f : 1.0f;
    for (const auto& p : *surface) {
      ASSERT_NEAR(p.normal_z, expected_z, 1e-5f) << "viewpoint z " << viewpoint_z;
    }
  }
}

TEST(Keypoints, BorderOfASquarePatchIsBoundaryInteriorIsNot) {
  const int n = 21;
  const auto surface = estimateNormals(gridPlane(n, 0.01f, 1.0f), NormalParams{}, Eigen::Vector3f::Zero());
  ASSERT_EQ(surface->size(), static_cast<size_t>(n * n));
  const auto keypoints = detectBoundaryKeypoints(*surface, KeypointParams{});
  const std::set<int> boundary(keypoints.begin(), keypoints.end());
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const int ring = std::min({i, j, n - 1 - i, n - 1 - j});  // steps from the border
      if (ring == 0) {
        EXPECT_TRUE(boundary.count(i * n + j)) << "border point " << i << "," << j;
      } else {
        EXPECT_FALSE(boundary.count(i * n + j)) << "interior point " << i << "," << j;
      }
    }
  }
}

// A curved, asymmetric patch (so every LRF axis is well defined) sampled at random.
XyzCloud curvedPatch(int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uv(-0.15f, 0.15f);
  XyzCloud cloud;
  for (int i = 0; i < count; ++i) {
    const float x = uv(rng), y = uv(rng);
    cloud.push_back(pcl::PointXYZ(x, y, 1.0f + 2.0f * x * x + 0.8f * y * y + 1.2f * x * y + 3.0f * x * x * x));
  }
  return cloud;
}

TEST(Describe, ShotAndLrfFollowARigidMotion) {
  const XyzCloud cloud = curvedPatch(4000, 11);
  const Eigen::Vector3f viewpoint(0.0f, 0.0f, 0.0f);
  const auto surface = estimateNormals(cloud, NormalParams{}, viewpoint);
  ASSERT_EQ(surface->size(), cloud.size());
  std::vector<int> keypoints;
  for (int i = 0; i < static_cast<int>(surface->size()) && keypoints.size() < 8; ++i) {
    if (surface->at(i).getVector3fMap().head<2>().norm() < 0.05f) keypoints.push_back(i);
  }
  const Features before = describe(*surface, keypoints, ShotParams{});
  ASSERT_EQ(before.size(), keypoints.size());
  expectUnitDescriptorsAndRotationFrames(before);

  const Eigen::Matrix3f rotation = Eigen::AngleAxisf(1.1f, Eigen::Vector3f(0.3f, -0.5f, 0.8f).normalized()).matrix();
  const Eigen::Vector3f translation(0.4f, -1.2f, 2.5f);
  XyzCloud moved;
  for (const auto& p : cloud) {
    const Eigen::Vector3f q = rotation * p.getVector3fMap() + translation;
    moved.push_back(pcl::PointXYZ(q.x(), q.y(), q.z()));
  }
  const auto moved_surface = estimateNormals(moved, NormalParams{}, rotation * viewpoint + translation);
  const Features after = describe(*moved_surface, keypoints, ShotParams{});
  ASSERT_EQ(after.size(), before.size());
  for (size_t i = 0; i < before.size(); ++i) {
    EXPECT_TRUE(after.positions[i].isApprox(rotation * before.positions[i] + translation, 1e-5f));
    // Rows are axes: each rotates with the cloud.
    EXPECT_TRUE(after.lrfs[i].isApprox(before.lrfs[i] * rotation.transpose(), 1e-3f))
        << "LRF " << i << "\n" << after.lrfs[i] << "\nvs\n" << before.lrfs[i] * rotation.transpose();
    EXPECT_LT((after.descriptors.row(i) - before.descriptors.row(i)).norm(), 1e-3f) << "descriptor " << i;
  }
}

TEST(Describe, KeypointWithTooFewNeighboursIsDropped) {
  const XyzCloud plane = curvedPatch(2000, 5);
  Surface::Ptr surface = estimateNormals(plane, NormalParams{}, Eigen::Vector3f::Zero());
  // A loose cluster of 6 points 1 m away: enough for PCL's LRF (5), not for min_neighbours = 10.
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> jitter(-0.01f, 0.01f);
  const int isolated = static_cast<int>(surface->size());
  for (int i = 0; i < 6; ++i) {
    pcl::PointNormal p;
    p.x = 1.0f + jitter(rng), p.y = 1.0f + jitter(rng), p.z = 1.0f + jitter(rng) * 0.2f;
    p.normal_x = 0.0f, p.normal_y = 0.0f, p.normal_z = -1.0f;
    surface->push_back(p);
  }
  const std::vector<int> keypoints = {0, isolated};
  ShotParams params;
  params.min_neighbours = 10;
  const Features strict = describe(*surface, keypoints, params);
  ASSERT_EQ(strict.size(), 1u);
  EXPECT_EQ(strict.positions[0], surface->at(0).getVector3fMap());
  // The same keypoint passes a looser threshold: it is the neighbour count that dropped it.
  params.min_neighbours = 5;
  EXPECT_EQ(describe(*surface, keypoints, params).size(), 2u);
}

// A 160x120 camera (Kinect's 525 px focal length scaled to a quarter of the size) sees a box
// (front face at 1.5 m) in front of a wall at 2 m. The columns from kVoidColumn on return
// nothing (wider than ContourParams::max_gap, so not a shadow to look across), and a 3x3 hole
// sits in the wall. The box covers columns kBoxCols and rows kBoxRows (inclusive).
constexpr int kWidth = 160, kHeight = 120, kVoidColumn = 110;
constexpr int kBoxCols[2] = {62, 97}, kBoxRows[2] = {46, 73};
constexpr int kHoleCol = 20, kHoleRow = 20;

bool onBox(int col, int row) {
  return col >= kBoxCols[0] && col <= kBoxCols[1] && row >= kBoxRows[0] && row <= kBoxRows[1];
}

Scene boxInFrontOfWall() {
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

TEST(OccludingContours, NearSideOfJumpsAndSilhouettesAgainstNothingOnly) {
  const Scene scene = boxInFrontOfWall();
  const ContourParams params;
  ASSERT_EQ(params.window, 2);
  ASSERT_LT(params.max_gap, kWidth - kVoidColumn);
  std::set<int> edges;
  for (int i : detectOccludingContourPixels(scene, params)) edges.insert(scene.pixel_index[i]);
  for (int v = 0; v < kHeight; ++v) {
    for (int u = 0; u < kVoidColumn; ++u) {
      bool expected;
      if (onBox(u, v)) {
        // The box's outer two pixel rings see the wall 50 cm behind within the window.
        expected = std::min({u - kBoxCols[0], kBoxCols[1] - u, v - kBoxRows[0], kBoxRows[1] - v}) < 2;
      } else {
        // The wall next to the box is its shadow and the wall around the hole sees the wall
        // again across it: neither is an edge. The last column before the void is a silhouette.
        expected = u == kVoidColumn - 1;
      }
      EXPECT_EQ(edges.count(v * kWidth + u) == 1, expected) << "pixel col " << u << " row " << v;
    }
  }

  Scene unorganized = scene;
  unorganized.pixel_index.clear();
  expectError([&] { detectOccludingContourPixels(unorganized, params); }, ErrorCode::kInvalidInput,
              "box scene: occluding-contour keypoints need an organized scene");
  ContourParams bad = params;
  bad.max_gap = 1;
  expectError([&] { detectOccludingContourPixels(scene, bad); }, ErrorCode::kInvalidInput, "contour.max_gap");
}

// Ground truth for the Kinect-noise scene below: the box and where its silhouette is.
constexpr float kBoxHalf = 0.25f, kBoxHeight = 0.6f;

float distanceToBox(const Eigen::Vector3f& p) {
  const Eigen::Vector3f lo(-kBoxHalf, -kBoxHalf, 0.0f), hi(kBoxHalf, kBoxHalf, kBoxHeight);
  const Eigen::Vector3f outside = (lo - p).cwiseMax(p - hi).cwiseMax(0.0f);
  const Eigen::Vector3f inside = (p - lo).cwiseMin(hi - p);
  return outside.norm() > 0 ? outside.norm() : inside.minCoeff();
}

// A 50 x 50 x 60 cm box on a floor, a wall 1.25 m behind it, seen by a Kinect (640x480, noise
// and disparity quantisation) 3 m from the box: floor and wall fill the whole image, so the
// box's silhouette is the only depth discontinuity.
SyntheticScene boxOnFloorBeforeWall() {
  SceneObject box{"box", testing::boxMesh({-kBoxHalf, -kBoxHalf, 0.0f}, {kBoxHalf, kBoxHalf, kBoxHeight}), 0, 0, 0};
  SceneObject wall{"wall", testing::boxMesh({-4.0f, 1.25f, 0.0f}, {4.0f, 1.35f, 3.0f}), 0, 0, 0};
  SyntheticSceneParams params;
  params.floor_size = 8.0f;
  // From above enough to see the top face at 24 degrees: from the default 1.2 m height it is
  // too grazing to keep a surface near its back edge after smoothing.
  params.camera_eye = {0.0f, -2.5f, 1.8f};
  params.camera_target = {0.0f, 0.0f, 0.3f};
  return composeScene({box, wall}, params);
}

TEST(OccludingContours, KinectNoiseFiresOnTheSilhouetteOnlyWhereBoundariesFireEverywhere) {
  const SyntheticScene synthetic = boxOnFloorBeforeWall();
  const Scene& scene = synthetic.scene;
  ASSERT_FALSE(scene.pixel_index.empty());
  const FrontEndParams params;
  ASSERT_EQ(params.keypoints.method, KeypointMethod::kAuto);
  const XyzCloud::Ptr points = smooth(*downsample(*scene.cloud, params.downsample), params.smoothing);
  const Surface::Ptr surface = estimateNormals(*points, params.normals, scene.sensor_origin);
  const std::vector<int> contour = detectKeypoints(scene, *surface, params.keypoints, params.downsample.leaf_size);
  std::vector<Eigen::Vector3f> positions;
  for (int k : contour) positions.push_back(surface->at(k).getVector3fMap());
  for (const auto& p : positions) {
    // Noise and the 2.9 cm disparity step at 3 m move box points this far off its faces.
    EXPECT_LT(distanceToBox(p), 0.04f) << "contour keypoint off the box: " << p.transpose();
  }
  // Silhouette seen from (0, -2.5, 1.8): the front vertical edges (against floor and wall; not at
  // the foot, where the floor behind is as near as the box) and the top's side and back edges.
  std::vector<Eigen::Vector3f> silhouette;
  for (float t = -0.2f; t <= 0.2f; t += 0.05f) {
    silhouette.emplace_back(-kBoxHalf, t, kBoxHeight);
    silhouette.emplace_back(kBoxHalf, t, kBoxHeight);
    silhouette.emplace_back(t, kBoxHalf, kBoxHeight);
  }
  for (float z = 0.25f; z <= 0.55f; z += 0.05f) {
    silhouette.emplace_back(-kBoxHalf, -kBoxHalf, z);
    silhouette.emplace_back(kBoxHalf, -kBoxHalf, z);
  }
  for (const auto& s : silhouette) {
    float nearest = 1e9f;
    for (const auto& p : positions) nearest = std::min(nearest, (p - s).norm());
    EXPECT_LT(nearest, 0.03f) << "no keypoint near the silhouette point " << s.transpose();
  }
  // The seed's detector on the same surface fires on the quantised floor and wall.
  KeypointParams boundary = params.keypoints;
  boundary.method = KeypointMethod::kBoundary;
  size_t off_box = 0;
  for (int k : detectKeypoints(scene, *surface, boundary, params.downsample.leaf_size)) {
    off_box += distanceToBox(surface->at(k).getVector3fMap()) > 0.05f;
  }
  std::cout << "box scene: " << surface->size() << " surface points, " << contour.size()
            << " contour keypoints, " << off_box << " boundary keypoints off the box\n";
  EXPECT_GT(off_box, 10 * contour.size());
}

// detectOccludingContourPixels as it was before it took a per-row formula for the pixels whose
// whole window has returns: every pixel scanned along the 8 directions. Its output must not
// change, so the faster version is compared with this one.
std::vector<int> occludingContourPixelsByScan(const Scene& scene, const ContourParams& params) {
  const int width = scene.image_width, height = scene.image_height;
  const size_t pixels = static_cast<size_t>(width) * static_cast<size_t>(height);
  std::vector<float> range(pixels, std::numeric_limits<float>::quiet_NaN());
  for (size_t i = 0; i < scene.pixel_index.size(); ++i) {
    range[scene.pixel_index[i]] = ((*scene.cloud)[i].getVector3fMap() - scene.sensor_origin).norm();
  }
  constexpr int kDirections[8][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {1, -1}, {-1, 1}, {-1, -1}};
  std::vector<uint8_t> is_edge(pixels, 0);
  for (int row = 0; row < height; ++row) {
    for (int col = 0; col < width; ++col) {
      const float r = range[static_cast<size_t>(row) * width + col];
      if (std::isnan(r)) continue;
      const float jump = std::max(params.min_jump, params.relative_jump * r);
      bool occluding = false, shadow = false;
      for (const auto& d : kDirections) {
        bool seen = false, left_image = false;
        for (int step = 1; step <= params.max_gap; ++step) {
          const int c = col + step * d[0], w = row + step * d[1];
          if (c < 0 || c >= width || w < 0 || w >= height) {
            left_image = true;
            break;
          }
          const float other = range[static_cast<size_t>(w) * width + c];
          if (!std::isnan(other)) {
            seen = true;
            occluding |= other - r > jump;
            shadow |= r - other > jump;
          }
          if (seen && step >= params.window) break;
        }
        occluding |= !seen && !left_image;
      }
      is_edge[static_cast<size_t>(row) * width + col] = occluding && !shadow;
    }
  }
  std::vector<int> edges;
  for (size_t i = 0; i < scene.pixel_index.size(); ++i) {
    if (is_edge[scene.pixel_index[i]]) edges.push_back(static_cast<int>(i));
  }
  return edges;
}

std::string describeContourParams(const ContourParams& p) {
  return "window " + std::to_string(p.window) + ", max_gap " + std::to_string(p.max_gap) + ", min_jump " +
         std::to_string(p.min_jump) + ", relative_jump " + std::to_string(p.relative_jump);
}

// A random organized scene: rectangles stepped in front of and behind a background by about
// the jumps the tests' ContourParams use (some sloped, some exactly at the threshold), runs of
// no return of random length and direction (up to twice the largest max_gap, also along and
// across the border), and the inputs loaders never give but the function accepts: points in
// any order, two on one pixel, NaN and infinite coordinates.
Scene randomContourScene(std::mt19937& rng, int width, int height) {
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  const auto chance = [&](float p) { return unit(rng) < p; };
  const auto uniform = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  // Ranges on a 1/64 m grid, seen straight along the z axis, are exact: with min_jump 1/16 a
  // jump then equals the threshold exactly, where > and >= part. Ranges a float step or two
  // off the grid just below a power of two are where a differently rounded comparison
  // (other > r + jump) parts.
  const bool exact = chance(0.3f);
  const float background = exact ? std::ldexp(1.0f, uniform(-1, 2)) - static_cast<float>(uniform(0, 4)) / 64.0f
                                 : 0.5f + 4.0f * unit(rng);
  std::vector<float> depth(static_cast<size_t>(width) * height, background);
  constexpr float kSteps[] = {0.01f, 0.03f, 0.05f, 0.0625f, 0.07f, 0.1f, 0.3f, 1.0f};
  for (int k = uniform(0, 6); k > 0; --k) {
    const int c0 = uniform(-3, width), r0 = uniform(-3, height);
    const int c1 = c0 + uniform(1, width), r1 = r0 + uniform(1, height);
    const float step = kSteps[uniform(0, 7)] * (chance(0.5f) ? 1.0f : -1.0f);
    const float slope = chance(0.3f) ? 0.05f * unit(rng) : 0.0f;
    for (int r = std::max(r0, 0); r < std::min(r1, height); ++r) {
      for (int c = std::max(c0, 0); c < std::min(c1, width); ++c) {
        float& z = depth[static_cast<size_t>(r) * width + c];
        z = std::max(0.2f, z + step + slope * static_cast<float>(c - c0));
      }
    }
  }
  std::normal_distribution<float> noise(0.0f, 0.003f);
  for (float& z : depth) {
    if (!exact) {
      if (chance(0.3f)) z += noise(rng);
      continue;
    }
    z = std::round(z * 64.0f) / 64.0f;
    if (chance(0.3f)) {
      const float towards = chance(0.5f) ? 0.0f : 10.0f;
      for (int k = uniform(1, 2); k > 0; --k) z = std::nextafter(z, towards);
    }
  }

  std::vector<uint8_t> hole(depth.size(), 0);
  constexpr int kDirections[8][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {1, -1}, {-1, 1}, {-1, -1}};
  for (int k = uniform(0, 10); k > 0; --k) {
    const auto& d = kDirections[uniform(0, 7)];
    const int length = uniform(1, 90), thickness = uniform(1, 3);
    const int c0 = uniform(0, width - 1), r0 = uniform(0, height - 1);
    for (int t = 0; t < thickness; ++t) {
      for (int s = 0; s < length; ++s) {
        const int c = c0 + s * d[0] - t * d[1], r = r0 + s * d[1] + t * d[0];  // t across the run
        if (c >= 0 && c < width && r >= 0 && r < height) hole[static_cast<size_t>(r) * width + c] = 1;
      }
    }
  }
  if (chance(0.2f)) {  // a whole border row or column, as Kinect frames often have
    const int side = uniform(0, 3);
    for (int r = 0; r < height; ++r) {
      for (int c = 0; c < width; ++c) {
        const bool border = (side == 0 && c == 0) || (side == 1 && c == width - 1) || (side == 2 && r == 0) ||
                            (side == 3 && r == height - 1);
        if (border) hole[static_cast<size_t>(r) * width + c] = 1;
      }
    }
  }

  Scene scene;
  scene.image_width = width;
  scene.image_height = height;
  scene.source = "random scene";
  if (!exact) scene.sensor_origin = Eigen::Vector3f(0.01f * unit(rng), -0.01f * unit(rng), 0.005f * unit(rng));
  const auto addPoint = [&](int pixel, const Eigen::Vector3f& p) {
    PointT q;
    q.x = p.x(), q.y = p.y(), q.z = p.z();
    scene.cloud->push_back(q);
    scene.pixel_index.push_back(pixel);
  };
  const auto pointAt = [&](int pixel, float z) {
    if (exact) return Eigen::Vector3f(0.0f, 0.0f, z);
    const float u = static_cast<float>(pixel % width) - 0.5f * width;
    const float v = static_cast<float>(pixel / width) - 0.5f * height;
    return Eigen::Vector3f(u * z / 100.0f, v * z / 100.0f, z);
  };
  for (int pixel = 0; pixel < width * height; ++pixel) {
    if (!hole[pixel]) addPoint(pixel, pointAt(pixel, depth[pixel]));
  }
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  if (chance(0.3f)) addPoint(uniform(0, width * height - 1), Eigen::Vector3f(nan, 0.0f, 1.0f));
  if (chance(0.2f)) addPoint(uniform(0, width * height - 1), Eigen::Vector3f(0.0f, 0.0f, inf));
  if (chance(0.3f) || scene.cloud->empty()) {
    const int pixel = uniform(0, width * height - 1);
    addPoint(pixel, pointAt(pixel, 0.5f + 4.0f * unit(rng)));
  }
  if (chance(0.5f)) {
    std::vector<size_t> order(scene.cloud->size());
    std::iota(order.begin(), order.end(), size_t{0});
    std::shuffle(order.begin(), order.end(), rng);
    Scene shuffled = scene;
    for (size_t i = 0; i < order.size(); ++i) {
      (*shuffled.cloud)[i] = (*scene.cloud)[order[i]];
      shuffled.pixel_index[i] = scene.pixel_index[order[i]];
    }
    return shuffled;
  }
  return scene;
}

// OpenMP's thread count for a scope. The tests that make thousands of calls on tiny images
// run on one: with more threads than free cores each parallel region waits for a thread that is
// not running (73 s instead of 0.4 s on a busy 2-core machine). Rows are independent; the real
// frame runs on several.
class ScopedThreads {
 public:
  explicit ScopedThreads(int threads) {
#ifdef _OPENMP
    omp_set_num_threads(threads);
#else
    (void)threads;
#endif
  }
  ~ScopedThreads() {
#ifdef _OPENMP
    omp_set_num_threads(previous_);
#endif
  }

 private:
#ifdef _OPENMP
  int previous_ = omp_get_max_threads();
#endif
};

TEST(OccludingContours, SameAsThePerPixelScanOnRandomScenes) {
  const ScopedThreads one_thread(1);
  std::mt19937 rng(7);
  std::vector<ContourParams> fixed(7);
  fixed[1].window = 1, fixed[1].max_gap = 1;
  fixed[2].window = 1, fixed[2].max_gap = 6, fixed[2].min_jump = 0.0625f, fixed[2].relative_jump = 0.0f;
  fixed[3].window = 3, fixed[3].max_gap = 3, fixed[3].min_jump = 0.02f, fixed[3].relative_jump = 0.1f;
  fixed[4].window = 3, fixed[4].max_gap = 12, fixed[4].min_jump = 0.0625f;
  fixed[5].window = 2, fixed[5].max_gap = 2, fixed[5].min_jump = 0.1f, fixed[5].relative_jump = 0.0f;
  fixed[6].window = 5, fixed[6].max_gap = 7, fixed[6].min_jump = 0.01f, fixed[6].relative_jump = 0.3f;
  size_t edges = 0, pixels = 0;
  for (int scene_number = 0; scene_number < 400; ++scene_number) {
    // Mostly small images, so that the border and the holes take a large share of the pixels,
    // down to a single row, column or pixel (no pixel then has its whole window inside).
    const bool large = scene_number % 10 == 0;
    const int width = large ? 160 : std::uniform_int_distribution<int>(1, 40)(rng);
    const int height = large ? 120 : std::uniform_int_distribution<int>(1, 30)(rng);
    const Scene scene = randomContourScene(rng, width, height);
    std::vector<ContourParams> settings = fixed;
    ContourParams random;
    random.window = std::uniform_int_distribution<int>(1, 4)(rng);
    random.max_gap = random.window + std::uniform_int_distribution<int>(0, 45)(rng);
    random.min_jump = std::uniform_real_distribution<float>(0.005f, 0.3f)(rng);
    random.relative_jump = scene_number % 3 == 0 ? 0.0f : std::uniform_real_distribution<float>(0.0f, 0.2f)(rng);
    settings.push_back(random);
    for (const ContourParams& params : settings) {
      const std::vector<int> expected = occludingContourPixelsByScan(scene, params);
      ASSERT_EQ(detectOccludingContourPixels(scene, params), expected)
          << "scene " << scene_number << " (" << width << "x" << height << "), " << describeContourParams(params);
      edges += expected.size();
      pixels += scene.pixel_index.size();
    }
  }
  // The scenes are no good if they have hardly any edges or nothing but edges.
  EXPECT_GT(edges, pixels / 50);
  EXPECT_LT(edges, pixels / 2);
  std::cout << "random scenes: " << edges << " edge pixels of " << pixels << "\n";
}

// A neighbour within a float step or two of r + jump or r - jump, where only the scan's own
// rounding (other - r > jump) gives its answer: other > r + jump, for one, differs there. The
// pixel is the centre of an image just large enough for its whole window, all of it at range r
// but that neighbour and, when it is the nearer one, the opposite neighbour far behind, so that
// whether it casts a shadow decides.
TEST(OccludingContours, SameAsThePerPixelScanAtTheThresholds) {
  const ScopedThreads one_thread(1);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<ContourParams> settings(4);
  settings[1].window = 1;
  settings[2].window = 3, settings[2].min_jump = 0.0625f, settings[2].relative_jump = 0.0f;
  settings[3].min_jump = 0.3f, settings[3].relative_jump = 0.0f;
  size_t centre_edges = 0, cases = 0;
  for (const ContourParams& params : settings) {
    const int size = 2 * params.window + 1, centre = params.window;
    for (int trial = 0; trial < 40; ++trial) {
      // Ranges up to 8 m, so that some r + jump round to a coarser float than r.
      const float r = std::ldexp(1.0f + unit(rng), std::uniform_int_distribution<int>(-2, 2)(rng));
      const float jump = std::max(params.min_jump, params.relative_jump * r);
      const int neighbour_row = centre + std::uniform_int_distribution<int>(-params.window, params.window)(rng);
      int neighbour_col = centre + std::uniform_int_distribution<int>(-params.window, params.window)(rng);
      if (neighbour_row == centre && neighbour_col == centre) ++neighbour_col;
      for (const float threshold : {r + jump, r - jump}) {
        for (int ulps = -2; ulps <= 2; ++ulps) {
          float other = threshold;
          for (int k = 0; k < std::abs(ulps); ++k) other = std::nextafter(other, ulps > 0 ? 100.0f : 0.0f);
          std::vector<float> depth(static_cast<size_t>(size) * size, r);
          depth[neighbour_row * size + neighbour_col] = other;
          if (other < r) depth[(2 * centre - neighbour_row) * size + 2 * centre - neighbour_col] = 2 * r + 1;
          Scene scene;
          scene.image_width = scene.image_height = size;
          for (int pixel = 0; pixel < size * size; ++pixel) {
            PointT p;
            p.x = p.y = 0.0f;  // along the z axis the range is z exactly
            p.z = depth[pixel];
            scene.cloud->push_back(p);
            scene.pixel_index.push_back(pixel);
          }
          const std::vector<int> expected = occludingContourPixelsByScan(scene, params);
          ASSERT_EQ(detectOccludingContourPixels(scene, params), expected)
              << describeContourParams(params) << ", r " << r << ", neighbour " << other;
          centre_edges += std::count(expected.begin(), expected.end(), centre * size + centre);
          ++cases;
        }
      }
    }
  }
  // Both answers occur: the centre is an edge when the neighbour is far enough behind it or,
  // when it is in front, not far enough.
  EXPECT_GT(centre_edges, 0u);
  EXPECT_LT(centre_edges, cases);
  std::cout << "thresholds: the centre is an edge in " << centre_edges << " of " << cases << " scenes\n";
}

TEST(OccludingContours, SameAsThePerPixelScanOnARealKinectFrame) {
  const std::string path = std::string(ISM_SHARED_DATA_DIR) + "/real/kinect/tum_desk.pcd";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data not present: " << path;
  const Scene scene = loadCloudFile(path);
  std::vector<ContourParams> settings(5);
  settings[1].window = 1;
  settings[2].window = 3;
  settings[3].max_gap = settings[3].window;
  settings[4].min_jump = 0.02f, settings[4].relative_jump = 0.0f;
  for (const ContourParams& params : settings) {
    const std::vector<int> expected = occludingContourPixelsByScan(scene, params);
    EXPECT_GT(expected.size(), 1000u) << describeContourParams(params);
    for (int threads : {1, 4}) {
      const ScopedThreads scoped(threads);
      EXPECT_EQ(detectOccludingContourPixels(scene, params), expected)
          << describeContourParams(params) << ", " << threads << " threads";
    }
  }
}

TEST(Keypoints, UnorganizedInputFallsBackToTheBoundaryTest) {
  const Scene organized = boxInFrontOfWall();
  Scene unorganized = organized;
  unorganized.pixel_index.clear();
  unorganized.image_width = unorganized.image_height = 0;
  EXPECT_EQ(resolveKeypointMethod(KeypointMethod::kAuto, organized), KeypointMethod::kOccludingContour);
  EXPECT_EQ(resolveKeypointMethod(KeypointMethod::kAuto, unorganized), KeypointMethod::kBoundary);
  EXPECT_EQ(resolveKeypointMethod(KeypointMethod::kBoundary, organized), KeypointMethod::kBoundary);

  const FrontEndParams params;
  const float leaf = params.downsample.leaf_size;
  const auto surface = estimateNormals(*downsample(*organized.cloud, params.downsample), params.normals,
                                       organized.sensor_origin);
  const std::vector<int> boundary = detectBoundaryKeypoints(*surface, params.keypoints);
  const std::vector<int> contour =
      nearestSurfacePoints(*surface, *organized.cloud, detectOccludingContourPixels(organized, params.keypoints.contour), leaf);
  ASSERT_FALSE(contour.empty());
  ASSERT_NE(boundary, contour);  // the boundary test also fires on the image border
  EXPECT_EQ(detectKeypoints(unorganized, *surface, params.keypoints, leaf), boundary);
  EXPECT_EQ(detectKeypoints(organized, *surface, params.keypoints, leaf), contour);

  KeypointParams forced = params.keypoints;
  forced.method = KeypointMethod::kOccludingContour;
  expectError([&] { detectKeypoints(unorganized, *surface, forced, leaf); }, ErrorCode::kInvalidInput,
              "need an organized scene");
}

TEST(Keypoints, EdgePointsSelectTheirNearestSurfacePointAndMinSpacingKeepsOnePerCell) {
  // 20 x 20 points at the centres of 1 cm voxels, from (0.005, 0.005) on: exactly 5 x 5 cells of 4 cm.
  const int n = 20;
  XyzCloud grid = gridPlane(n, 0.01f, 1.005f);
  for (auto& p : grid) p.x += 0.1f, p.y += 0.1f;
  const auto surface = estimateNormals(grid, NormalParams{}, Eigen::Vector3f::Zero());
  ASSERT_EQ(surface->size(), grid.size());
  // Two raw points, each in the voxel of one surface point, and a third 2 cm off the plane.
  Cloud raw;
  PointT a, b, c;
  a.getVector3fMap() = surface->at(21).getVector3fMap() + Eigen::Vector3f(0.004f, -0.004f, 0.004f);
  b.getVector3fMap() = surface->at(250).getVector3fMap() + Eigen::Vector3f(-0.004f, 0.0f, -0.004f);
  c.getVector3fMap() = surface->at(250).getVector3fMap() + Eigen::Vector3f(0.0f, 0.0f, 0.02f);
  raw.push_back(a), raw.push_back(b), raw.push_back(c);
  EXPECT_EQ(nearestSurfacePoints(*surface, raw, {0, 1, 2}, 0.01f), (std::vector<int>{21, 250}));
  expectError([&] { nearestSurfacePoints(*surface, raw, {3}, 0.01f); }, ErrorCode::kInvalidInput,
              "edge point index 3");

  std::vector<int> all(surface->size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  EXPECT_EQ(thinKeypoints(*surface, all, 0.0f), all);
  // The first point of each cell in row-major order is its corner point.
  std::vector<int> corners;
  for (int i = 0; i < n; i += 4) {
    for (int j = 0; j < n; j += 4) corners.push_back(i * n + j);
  }
  EXPECT_EQ(thinKeypoints(*surface, all, 0.04f), corners);
  expectError([&] { thinKeypoints(*surface, all, -1.0f); }, ErrorCode::kInvalidInput, "keypoints.min_spacing");
}

TEST(ExtractFeatures, BoxSceneKeypointsLieOnTheBoxOutlineAndStagesAreTimed) {
  const Scene scene = boxInFrontOfWall();
  StageTimings timings;
  const FrontEndResult result = extractFeatures(scene, FrontEndParams{}, /*apply_smoothing=*/true, &timings);
  std::vector<std::string> names;
  for (const auto& stage : timings.stages) names.push_back(stage.first);
  // An organized scene's keypoints come first: normals are computed only around them.
  EXPECT_EQ(names, (std::vector<std::string>{"downsample", "smooth", "keypoints", "normals", "describe"}));
  // A model trained with `ism-train --no-scene-smoothing` stores this: scenes then skip MLS.
  FrontEndParams unsmoothed;
  unsmoothed.smoothing.enabled = false;
  StageTimings unsmoothed_timings;
  extractFeatures(scene, unsmoothed, /*apply_smoothing=*/true, &unsmoothed_timings);
  names.clear();
  for (const auto& stage : unsmoothed_timings.stages) names.push_back(stage.first);
  EXPECT_EQ(names, (std::vector<std::string>{"downsample", "keypoints", "normals", "describe"}));
  // The boundary test reads every point's normal.
  Scene unorganized = scene;
  unorganized.pixel_index.clear();
  StageTimings boundary_timings;
  extractFeatures(unorganized, unsmoothed, /*apply_smoothing=*/true, &boundary_timings);
  names.clear();
  for (const auto& stage : boundary_timings.stages) names.push_back(stage.first);
  EXPECT_EQ(names, (std::vector<std::string>{"downsample", "normals", "keypoints", "describe"}));
  EXPECT_EQ(result.input_points, scene.cloud->size());
  EXPECT_GE(result.keypoint_candidates, result.features.size());
  ASSERT_GT(result.features.size(), 50u);
  expectUnitDescriptorsAndRotationFrames(result.features);
  // The box's front face spans x in [-0.2, 0.2), y in [-0.15, 0.15) at z = 1.5 (pixel centres
  // 62..97 and 46..73 back-projected); the wall's only edge is its silhouette against the void.
  const float void_x = (kVoidColumn - 1 - 79.5f) / 131.25f * 2.0f;
  for (const auto& p : result.features.positions) {
    if (p.z() < 1.75f) {
      const float dx = std::abs(std::abs(p.x()) - 0.2f), dy = std::abs(std::abs(p.y()) - 0.15f);
      EXPECT_LT(std::min(dx, dy), 0.03f) << "keypoint inside the box face: " << p.transpose();
    } else {
      EXPECT_NEAR(p.x(), void_x, 0.03f) << "keypoint on the wall away from its silhouette: " << p.transpose();
    }
  }
}

// extractFeatures computes an organized scene's normals only near its keypoints; the features
// must be exactly those of the stages run on every point's normal.
void expectFeaturesOfTheFullSurface(const Scene& scene, const FrontEndParams& params) {
  const FrontEndResult result = extractFeatures(scene, params, /*apply_smoothing=*/true);
  const XyzCloud::Ptr points = params.smoothing.enabled ? smooth(*downsample(*scene.cloud, params.downsample), params.smoothing)
                                                        : downsample(*scene.cloud, params.downsample);
  const Surface::Ptr full = estimateNormals(*points, params.normals, scene.sensor_origin);
  const std::vector<int> keypoints = detectKeypoints(scene, *full, params.keypoints, params.downsample.leaf_size);
  const Features expected = describe(*full, keypoints, params.shot);
  EXPECT_EQ(result.surface_points, points->size());
  EXPECT_EQ(result.keypoint_candidates, keypoints.size());
  EXPECT_LT(result.surface->size(), full->size()) << "every normal was computed";
  ASSERT_GT(expected.size(), 10u);
  EXPECT_EQ(result.features.positions, expected.positions);
  EXPECT_EQ(result.features.lrfs, expected.lrfs);
  EXPECT_EQ(result.features.descriptors, expected.descriptors);
}

TEST(ExtractFeatures, NormalsNearTheKeypointsGiveTheFeaturesOfTheWholeSurface) {
  FrontEndParams params;
  expectFeaturesOfTheFullSurface(boxOnFloorBeforeWall().scene, params);
  params.smoothing.enabled = false;
  expectFeaturesOfTheFullSurface(boxOnFloorBeforeWall().scene, params);
  params.keypoints.min_spacing = 0.03f;
  expectFeaturesOfTheFullSurface(boxOnFloorBeforeWall().scene, params);
  const std::string path = std::string(ISM_SHARED_DATA_DIR) + "/real/kinect/tum_desk.pcd";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data not present: " << path;
  params.keypoints.min_spacing = 0.0f;
  expectFeaturesOfTheFullSurface(loadCloudFile(path), params);
}

#ifdef _OPENMP
TEST(ExtractFeatures, OneThreadAndSeveralGiveTheSameFeatures) {
  // The server runs each request with its own OpenMP thread count; results must not depend on it.
  const Scene scene = boxInFrontOfWall();
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const FrontEndResult one = extractFeatures(scene, FrontEndParams{}, true);
  omp_set_num_threads(4);
  const FrontEndResult four = extractFeatures(scene, FrontEndParams{}, true);
  omp_set_num_threads(threads);
  ASSERT_EQ(one.surface->size(), four.surface->size());
  for (size_t i = 0; i < one.surface->size(); ++i) {
    ASSERT_EQ((*one.surface)[i].getVector3fMap(), (*four.surface)[i].getVector3fMap()) << i;
  }
  EXPECT_EQ(one.features.positions, four.features.positions);
  EXPECT_EQ(one.features.descriptors, four.features.descriptors);
}
#endif

TEST(ExtractFeatures, StopsWhenAskedAndValidatesInput) {
  const Scene scene = boxInFrontOfWall();
  int polls = 0;
  expectError([&] { extractFeatures(scene, FrontEndParams{}, true, nullptr, [&] { return ++polls > 1; }); },
              ErrorCode::kCancelled, "stopped during downsample");

  FrontEndParams bad;
  bad.shot.radius = 0.0f;
  expectError([&] { extractFeatures(scene, bad, false); }, ErrorCode::kInvalidInput, "shot.radius");
  Scene empty;
  empty.source = "empty.pcd";
  expectError([&] { extractFeatures(empty, FrontEndParams{}, false); }, ErrorCode::kInvalidInput, "empty.pcd");
}

TEST(ExtractFeatures, RealKinectFrame) {
  const std::string path = std::string(ISM_SHARED_DATA_DIR) + "/real/kinect/tum_desk.pcd";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data not present: " << path;
  const Scene scene = loadCloudFile(path);
  StageTimings timings;
  const FrontEndResult result = extractFeatures(scene, FrontEndParams{}, /*apply_smoothing=*/true, &timings);
  std::cout << "tum_desk: " << result.input_points << " points -> " << result.surface_points << " surface ("
            << result.surface->size() << " with normals) -> " << result.keypoint_candidates << " keypoints -> "
            << result.features.size() << " features;";
  for (const auto& stage : timings.stages) std::cout << " " << stage.first << " " << stage.second << " ms";
  std::cout << "; total " << timings.total() << " ms\n";
  // The README's comparison: the seed's boundary test on the same frame.
  FrontEndParams boundary;
  boundary.keypoints.method = KeypointMethod::kBoundary;
  std::cout << "tum_desk, boundary test: " << extractFeatures(scene, boundary, true).keypoint_candidates
            << " keypoints\n";
  EXPECT_GT(result.surface_points, 10000u);
  EXPECT_GT(result.features.size(), 1000u);
  // The seed's boundary test makes 14,561 of the 83,948 points keypoints, mostly on the
  // quantised floor and walls; occluding contours keep 4% (measured 3,393).
  EXPECT_LT(result.keypoint_candidates, result.surface_points / 10);
  // SHOT reads the normals within 8 cm of a keypoint: 28% of this frame's points (measured 23,590).
  EXPECT_LT(result.surface->size(), result.surface_points / 2);
  expectUnitDescriptorsAndRotationFrames(result.features);
}

Model modelWithOneCategory() {
  Model model;
  CategoryModel chair;
  chair.name = "chair";
  chair.bin_size = 0.1f;
  model.categories.push_back(chair);
  return model;
}

TEST(ModelFile, KeypointParametersRoundTripAndOldFilesLoadAsBoundary) {
  Model model = modelWithOneCategory();
  EXPECT_EQ(model.front_end.keypoints.method, KeypointMethod::kAuto) << "new models default to kAuto";
  KeypointParams& k = model.front_end.keypoints;
  k.method = KeypointMethod::kOccludingContour;
  k.contour.window = 3;
  k.contour.min_jump = 0.04f;
  k.contour.relative_jump = 0.09f;
  k.contour.max_gap = 25;
  k.min_spacing = 0.02f;
  const std::string bytes = serializeModel(model);
  const KeypointParams loaded = parseModel(bytes, "new.ismm").front_end.keypoints;
  EXPECT_EQ(loaded.method, KeypointMethod::kOccludingContour);
  EXPECT_EQ(loaded.contour.window, 3);
  EXPECT_EQ(loaded.contour.min_jump, 0.04f);
  EXPECT_EQ(loaded.contour.relative_jump, 0.09f);
  EXPECT_EQ(loaded.contour.max_gap, 25);
  EXPECT_EQ(loaded.min_spacing, 0.02f);
  for (KeypointMethod method : {KeypointMethod::kAuto, KeypointMethod::kBoundary}) {
    k.method = method;
    EXPECT_EQ(parseModel(serializeModel(model), "new.ismm").front_end.keypoints.method, method);
  }

  // A file written before the keypoint fields existed: its payload has none of them.
  v1::ModelFile file;
  ASSERT_TRUE(file.ParseFromString(bytes));
  v1::ModelData data;
  ASSERT_TRUE(data.ParseFromString(file.payload()));
  auto* fe = data.mutable_front_end();
  fe->clear_keypoint_method(), fe->clear_contour_window(), fe->clear_contour_min_jump();
  fe->clear_contour_relative_jump(), fe->clear_contour_max_gap(), fe->clear_keypoint_min_spacing();
  const auto resealed = [&file](const v1::ModelData& payload) {
    file.set_payload(payload.SerializeAsString());
    file.set_payload_crc32(static_cast<uint32_t>(
        crc32(0L, reinterpret_cast<const Bytef*>(file.payload().data()), static_cast<uInt>(file.payload().size()))));
    return file.SerializeAsString();
  };
  const KeypointParams old = parseModel(resealed(data), "old.ismm").front_end.keypoints;
  EXPECT_EQ(old.method, KeypointMethod::kBoundary);
  EXPECT_EQ(old.min_spacing, 0.0f);

  fe->set_keypoint_method(v1::FrontEndParams::KEYPOINT_METHOD_AUTO);  // contour fields still unset
  expectError([&] { parseModel(resealed(data), "broken.ismm"); }, ErrorCode::kCorruptModel,
              "contour parameters are invalid");
}

}  // namespace
}  // namespace ism

// --- The neighbour grid against brute force, and smoothing against PCL's MLS ---------------

namespace ism {
namespace {

std::vector<Eigen::Vector3f> randomSurfacePoints(size_t n, unsigned seed) {
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

std::set<int> bruteForce(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector3f& q, float r) {
  std::set<int> found;
  for (size_t i = 0; i < points.size(); ++i) {
    if ((points[i] - q).squaredNorm() <= r * r) found.insert(static_cast<int>(i));
  }
  return found;
}

TEST(NeighbourGrid, RadiusSearchNearestAndForEachPointMatchBruteForce) {
  const auto points = randomSurfacePoints(3000, 7);
  const NeighbourGrid grid(points, 0.05f);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-0.7f, 0.7f);
  for (float r : {0.01f, 0.05f, 0.12f}) {  // below, at and above the cell size
    for (int t = 0; t < 200; ++t) {
      const Eigen::Vector3f q(u(rng), u(rng), u(rng) * 0.2f);
      std::vector<int> indices;
      std::vector<float> distances;
      grid.radiusSearch(q, r, indices, distances);
      ASSERT_EQ(std::set<int>(indices.begin(), indices.end()), bruteForce(points, q, r));
      for (size_t i = 0; i < indices.size(); ++i) {
        EXPECT_FLOAT_EQ(distances[i], (points[static_cast<size_t>(indices[i])] - q).squaredNorm());
      }
      const auto exact = bruteForce(points, q, r);
      int best = -1;
      for (int i : exact) {
        if (best < 0 || (points[i] - q).squaredNorm() < (points[best] - q).squaredNorm()) best = i;
      }
      EXPECT_EQ(grid.nearest(q, r), best);
      // Only the allowed points (every third) count.
      std::vector<uint8_t> allowed(points.size(), 0);
      for (size_t i = 0; i < points.size(); i += 3) allowed[i] = 1;
      int best_allowed = -1;
      for (int i : exact) {
        if (allowed[i] && (best_allowed < 0 || (points[i] - q).squaredNorm() < (points[best_allowed] - q).squaredNorm())) {
          best_allowed = i;
        }
      }
      EXPECT_EQ(grid.nearest(q, r, &allowed), best_allowed);
    }
  }
  std::vector<std::set<int>> visited(points.size());
  grid.forEachPoint(0.05f, [&](int i, const std::vector<int>& n) { visited[i] = std::set<int>(n.begin(), n.end()); });
  for (size_t i = 0; i < points.size(); ++i) ASSERT_EQ(visited[i], bruteForce(points, points[i], 0.05f)) << i;
  // Visiting some points gives them the same neighbour lists, in the same order.
  std::vector<std::vector<int>> all(points.size()), some(points.size());
  grid.forEachPoint(0.05f, [&](int i, const std::vector<int>& n) { all[i] = n; });
  std::vector<uint8_t> only(points.size(), 0);
  for (size_t i = 0; i < points.size(); i += 7) only[i] = 1;
  grid.forEachPoint(0.05f, [&](int i, const std::vector<int>& n) { some[i] = n; }, &only);
  for (size_t i = 0; i < points.size(); ++i) {
    if (only[i]) {
      ASSERT_EQ(some[i], all[i]) << i;
    } else {
      ASSERT_TRUE(some[i].empty()) << "point " << i << " was not asked for";
    }
  }
  std::vector<int> capped;
  std::vector<float> unused;
  EXPECT_EQ(grid.radiusSearch(points[0], 0.3f, capped, unused, 5), 5u);
}

TEST(NeighbourGrid, AGridOverPartOfTheCloudFindsTheSameNeighboursInTheSameOrder) {
  // SHOT's grid over the points that have normals must answer as one over every point: cells
  // are fixed by the cell size, not by where the cloud's median lies.
  const auto points = randomSurfacePoints(4000, 11);
  std::vector<Eigen::Vector3f> half;
  std::vector<int> index_in_full;
  for (size_t i = 0; i < points.size(); ++i) {
    if (points[i].x() < 0.1f) {  // shifts the median by a fraction of a cell
      half.push_back(points[i]);
      index_in_full.push_back(static_cast<int>(i));
    }
  }
  const NeighbourGrid full(points, 0.08f), part(half, 0.08f);
  std::vector<int> in_full, in_part;
  std::vector<float> d_full, d_part;
  for (size_t q = 0; q < half.size(); q += 5) {
    full.radiusSearch(half[q], 0.08f, in_full, d_full);
    part.radiusSearch(half[q], 0.08f, in_part, d_part);
    std::vector<int> expected;
    for (int i : in_full) {
      if (points[static_cast<size_t>(i)].x() < 0.1f) expected.push_back(i);
    }
    for (int& i : in_part) i = index_in_full[static_cast<size_t>(i)];
    ASSERT_EQ(in_part, expected) << q;
  }
}

TEST(NeighbourGrid, ExtremeAndDegenerateInputsStayExact) {
  // Points kilometres apart share clamped cells; the exact distance test still separates them.
  std::vector<Eigen::Vector3f> points = {{0, 0, 0}, {0.01f, 0, 0}, {1e30f, 0, 0}, {-1e30f, 5, 5}, {3e4f, 0, 0}};
  const NeighbourGrid grid(points, 0.01f);
  std::vector<int> indices;
  std::vector<float> distances;
  grid.radiusSearch({0, 0, 0}, 0.02f, indices, distances);
  EXPECT_EQ(std::set<int>(indices.begin(), indices.end()), (std::set<int>{0, 1}));
  grid.radiusSearch({1e30f, 0, 0}, 1.0f, indices, distances);
  EXPECT_EQ(indices, std::vector<int>{2});
  EXPECT_EQ(grid.nearest({0.004f, 0, 0}, 0.01f), 0);
  EXPECT_EQ(grid.nearest({5, 5, 5}, 0.01f), -1);
  grid.radiusSearch({std::nanf(""), 0, 0}, 1.0f, indices, distances);
  EXPECT_TRUE(indices.empty());
  EXPECT_EQ(NeighbourGrid(std::vector<Eigen::Vector3f>{}, 0.01f).nearest({0, 0, 0}, 1), -1);
  testing::expectError([] { NeighbourGrid(std::vector<Eigen::Vector3f>{}, 0.0f); }, ErrorCode::kInvalidInput, "cell size");
}

TEST(NeighbourGrid, AFarOutlierDoesNotMergeTheCellsOfTheRest) {
  // One point 100 km away used to stretch the grid so far that all others shared a few clamped
  // cells. forEachPoint then offers each point every point of those cells as a candidate; with
  // distinct cells a point on a 1 cm lattice sees at most 27 cells of 3 cm, i.e. 27 * 27 points.
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < 60; ++i) {
    for (int j = 0; j < 60; ++j) points.emplace_back(0.01f * i, 0.01f * j, 1.0f);
  }
  points.emplace_back(-1e5f, 0.0f, 0.0f);
  const NeighbourGrid grid(points, 0.03f);
  std::vector<int> indices;
  std::vector<float> distances;
  for (size_t i = 0; i + 1 < points.size(); i += 97) {
    grid.radiusSearch(points[i], 0.03f, indices, distances);
    EXPECT_EQ(std::set<int>(indices.begin(), indices.end()), bruteForce(points, points[i], 0.03f));
  }
  EXPECT_LE(grid.candidates(points[0], 0.03f), 27u * 27u);
}

TEST(NeighbourGrid, PointsWithinIsTheUnionOfRadiusSearches) {
  // Every way pointsWithin decides: whole cells by their box, point by point, every cell when
  // the radius spans more cells than are occupied, no box tests when r^2 underflows, and point
  // by point in the clamped cells of far outliers.
  auto points = randomSurfacePoints(5000, 23);
  points.emplace_back(1e5f, 0.0f, 0.0f);
  points.emplace_back(1e5f, 0.01f, 0.0f);
  points.push_back(points[10]);  // a repeated point
  const NeighbourGrid grid(points, 0.03f);
  std::vector<Eigen::Vector3f> queries;
  for (size_t i = 0; i < 5000; i += 53) queries.push_back(points[i]);
  queries.push_back(points[5000]);
  queries.emplace_back(std::nanf(""), 0.0f, 0.0f);  // finds nothing
  queries.emplace_back(0.3f, -0.2f, 0.05f);        // not a point of the cloud
  for (float r : {0.0f, 1e-20f, 0.01f, 0.03f, 0.08f, 0.2f, 50.0f}) {
    std::vector<uint8_t> expected(points.size(), 0);
    std::vector<int> indices;
    std::vector<float> distances;
    for (const auto& q : queries) {
      grid.radiusSearch(q, r, indices, distances);
      for (int i : indices) expected[static_cast<size_t>(i)] = 1;
    }
    EXPECT_EQ(grid.pointsWithin(queries, r), expected) << "radius " << r;
  }
  EXPECT_EQ(grid.pointsWithin(queries, -1.0f), std::vector<uint8_t>(points.size(), 0));
}

TEST(NeighbourGrid, PclSearchInterfaceFindsTheKNearest) {
  const auto points = randomSurfacePoints(2000, 11);
  pcl::PointCloud<pcl::PointNormal>::Ptr cloud(new pcl::PointCloud<pcl::PointNormal>);
  for (const auto& p : points) {
    pcl::PointNormal q;
    q.getVector3fMap() = p;
    cloud->push_back(q);
  }
  GridSearch<pcl::PointNormal> search(0.05f);
  search.setInputCloud(cloud);
  pcl::PointNormal query;
  query.getVector3fMap() = Eigen::Vector3f(3, 3, 3);  // far outside: the radius has to grow
  pcl::Indices k_indices;
  std::vector<float> k_distances;
  ASSERT_EQ(search.nearestKSearch(query, 4, k_indices, k_distances), 4);
  std::vector<std::pair<float, int>> all;
  for (size_t i = 0; i < points.size(); ++i) all.emplace_back((points[i] - query.getVector3fMap()).squaredNorm(), static_cast<int>(i));
  std::sort(all.begin(), all.end());
  for (int i = 0; i < 4; ++i) EXPECT_EQ(k_indices[static_cast<size_t>(i)], all[static_cast<size_t>(i)].second);
  EXPECT_TRUE(std::is_sorted(k_distances.begin(), k_distances.end()));
}

// NormalEstimator reads the neighbours' coordinates from the grid and sums PCL's covariance
// itself, and marks the points near the centres cell by cell. What it computes has to stay
// what it computed before, bit for bit: pcl::computePointNormal over each point's neighbour
// list. That list's ORDER matters as much as its members, since PCL shifts the coordinates by
// the first neighbour and sums in list order: the grid lists neighbours by cell
// floor(p / cell) in x, then y, then z, and by index within a cell. The reference below finds
// every set by brute force (with the grid's float distance test) and orders it so.
class BruteForce {
 public:
  explicit BruteForce(const XyzCloud& cloud) : cloud_(cloud), order_(cloud.size()) {
    std::iota(order_.begin(), order_.end(), 0);
    std::sort(order_.begin(), order_.end(), [&](int a, int b) { return cloud[a].x < cloud[b].x; });
    for (int i : order_) xs_.push_back(cloud[static_cast<size_t>(i)].x);
  }
  // The grid's test: (dx * dx + dy * dy) + dz * dz <= r * r, in float.
  static bool within(const pcl::PointXYZ& p, const Eigen::Vector3f& q, float r) {
    const float dx = p.x - q.x(), dy = p.y - q.y(), dz = p.z - q.z();
    const float d2 = dx * dx + dy * dy + dz * dz;
    return d2 <= r * r;
  }
  // The points within r of q, ascending. Points sorted by x only narrow the search: any point
  // within r is within 2 r along x.
  std::vector<int> near(const Eigen::Vector3f& q, float r) const {
    std::vector<int> found;
    const auto first = std::lower_bound(xs_.begin(), xs_.end(), q.x() - 2 * r);
    const auto last = std::upper_bound(xs_.begin(), xs_.end(), q.x() + 2 * r);
    for (auto it = first; it != last; ++it) {
      const int i = order_[static_cast<size_t>(it - xs_.begin())];
      if (within(cloud_[static_cast<size_t>(i)], q, r)) found.push_back(i);
    }
    std::sort(found.begin(), found.end());
    return found;
  }

 private:
  const XyzCloud& cloud_;
  std::vector<int> order_;
  std::vector<float> xs_;
};

// The flags that differ, by index: a diff of the whole vectors would print only their heads.
void expectSameFlags(const std::vector<uint8_t>& actual, const std::vector<uint8_t>& expected, const char* what) {
  ASSERT_EQ(actual.size(), expected.size()) << what;
  size_t differing = 0;
  for (size_t i = 0; i < actual.size(); ++i) {
    if (actual[i] != expected[i] && ++differing <= 3) {
      ADD_FAILURE() << what << ": point " << i << " is " << int{actual[i]} << ", brute force says " << int{expected[i]};
    }
  }
  EXPECT_EQ(differing, 0u) << what;
}

uint32_t bitsOf(float v) {  // == would take -0 for 0
  uint32_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  return bits;
}

// NormalEstimator as the front end drives it (the normals within 1 cm of some points, then those
// within 8 cm of all centres) against pcl::computePointNormal over brute-force neighbour lists
// in the grid's order, flipped towards the viewpoint, with one thread and with several.
void expectNormalsAsPclComputesThem(const XyzCloud& cloud, const std::vector<int>& centres,
                                    const Eigen::Vector3f& viewpoint) {
  const NormalParams params;
  const float kNearPixel = 0.01f, kSupport = 0.08f;
  const BruteForce brute(cloud);
  const std::vector<int> few(centres.begin(), centres.begin() + static_cast<std::ptrdiff_t>(centres.size() / 3));
  std::vector<Eigen::Vector3f> queries;
  for (int c : centres) queries.push_back(cloud[static_cast<size_t>(c)].getVector3fMap());
  queries.push_back(Eigen::Vector3f(std::nanf(""), 0.0f, 0.0f));  // finds nothing
  std::vector<uint8_t> near_centres(cloud.size(), 0), wanted(cloud.size(), 0);
  for (const auto& q : queries) {
    for (int i : brute.near(q, kSupport)) near_centres[static_cast<size_t>(i)] = 1;
  }
  wanted = near_centres;
  for (int c : few) {
    for (int i : brute.near(cloud[static_cast<size_t>(c)].getVector3fMap(), kNearPixel)) wanted[static_cast<size_t>(i)] = 1;
  }
  // The reference, point by point.
  const double inverse_cell = 1.0 / static_cast<double>(params.radius);
  const auto cell = [&](int i) {
    const Eigen::Vector3d scaled = cloud[static_cast<size_t>(i)].getVector3fMap().cast<double>() * inverse_cell;
    return std::make_tuple(std::floor(scaled.x()), std::floor(scaled.y()), std::floor(scaled.z()), i);
  };
  std::vector<pcl::PointNormal> expected(cloud.size());
  std::vector<uint8_t> defined(cloud.size(), 0);
  size_t undefined = 0;
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (!wanted[i]) continue;
    std::vector<int> neighbours = brute.near(cloud[i].getVector3fMap(), params.radius);
    std::sort(neighbours.begin(), neighbours.end(), [&](int a, int b) { return cell(a) < cell(b); });
    Eigen::Vector4f plane;
    float curvature;
    if (!pcl::computePointNormal(cloud, neighbours, plane, curvature) || !plane.head<3>().allFinite()) {
      ++undefined;
      continue;
    }
    pcl::flipNormalTowardsViewpoint(cloud[i], viewpoint.x(), viewpoint.y(), viewpoint.z(), plane);
    pcl::PointNormal& p = expected[i];
    p.x = cloud[i].x, p.y = cloud[i].y, p.z = cloud[i].z;
    p.normal_x = plane[0], p.normal_y = plane[1], p.normal_z = plane[2];
    p.curvature = curvature;
    defined[i] = 1;
  }
  ASSERT_GT(std::count(defined.begin(), defined.end(), 1), 1000);
  std::vector<int> thread_counts = {1};
#ifdef _OPENMP
  const int threads = omp_get_max_threads();
  thread_counts.push_back(3);
#endif
  for (int t : thread_counts) {
#ifdef _OPENMP
    omp_set_num_threads(t);
#endif
    SCOPED_TRACE(std::to_string(t) + " threads");
    NormalEstimator estimator(cloud, params, viewpoint);
    expectSameFlags(estimator.pointsNear(queries, kSupport), near_centres, "pointsNear");
    estimator.computeNear(few, kNearPixel);
    estimator.computeNear(centres, kSupport);
    std::vector<int> index_in_surface;
    const Surface::Ptr surface = estimator.surface(&index_in_surface);
    expectSameFlags(estimator.defined(), defined, "defined");
    EXPECT_EQ(surface->size(), static_cast<size_t>(std::count(defined.begin(), defined.end(), 1)));
    size_t mismatches = 0;
    for (size_t i = 0; i < cloud.size(); ++i) {
      if (!defined[i] || index_in_surface[i] < 0) continue;
      const pcl::PointNormal &ours = (*surface)[static_cast<size_t>(index_in_surface[i])], &theirs = expected[i];
      const bool same = bitsOf(ours.x) == bitsOf(theirs.x) && bitsOf(ours.y) == bitsOf(theirs.y) &&
                        bitsOf(ours.z) == bitsOf(theirs.z) && bitsOf(ours.normal_x) == bitsOf(theirs.normal_x) &&
                        bitsOf(ours.normal_y) == bitsOf(theirs.normal_y) && bitsOf(ours.normal_z) == bitsOf(theirs.normal_z) &&
                        bitsOf(ours.curvature) == bitsOf(theirs.curvature);
      if (!same && ++mismatches <= 3) {
        ADD_FAILURE() << "point " << i << ": normal " << ours.getNormalVector3fMap().transpose() << " curvature "
                      << ours.curvature << ", PCL " << theirs.getNormalVector3fMap().transpose() << " curvature "
                      << theirs.curvature;
      }
    }
    EXPECT_EQ(mismatches, 0u);
  }
#ifdef _OPENMP
  omp_set_num_threads(threads);
#endif
  std::cout << cloud.size() << " points, " << centres.size() << " centres: " << std::count(wanted.begin(), wanted.end(), 1)
            << " normals asked for, " << undefined << " of them undefined\n";
}

TEST(Normals, NearTheCentresAreBitForBitPclsOverNeighboursInTheGridsOrder) {
  // Synthetic: a wavy sheet with scattered points (random coordinates), a lattice whose
  // distances tie, and a few points repeated (equal coordinates, distance 0).
  XyzCloud cloud;
  for (const auto& p : randomSurfacePoints(30000, 17)) cloud.push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  for (const auto& p : gridPlane(60, 0.01f, 0.35f)) cloud.push_back(p);
  for (int i = 0; i < 30000; i += 1000) cloud.push_back(cloud[static_cast<size_t>(i)]);
  std::vector<int> centres;  // on part of the sheet, so that the normals asked for end inside it
  for (size_t i = 0; i < cloud.size(); i += 37) {
    if (cloud[i].x < 0.0f) centres.push_back(static_cast<int>(i));
  }
  expectNormalsAsPclComputesThem(cloud, centres, Eigen::Vector3f(0.1f, -0.2f, 2.0f));

  const std::string path = std::string(ISM_SHARED_DATA_DIR) + "/real/kinect/tum_desk.pcd";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data not present: " << path;
  // The front end's frame: its downsampled points and contour keypoints.
  const Scene scene = loadCloudFile(path);
  const FrontEndParams params;
  const XyzCloud::Ptr points = downsample(*scene.cloud, params.downsample);
  NormalEstimator keypoint_normals(*points, params.normals, scene.sensor_origin);
  const std::vector<int> keypoints =
      detectContourKeypoints(scene, keypoint_normals, params.keypoints, params.downsample.leaf_size);
  expectNormalsAsPclComputesThem(*points, keypoints, scene.sensor_origin);
}

TEST(Smooth, NearlyCollinearNeighboursNeverThrowAPointAway) {
  // Points on a line with sub-micrometre jitter: plane and polynomial fit are degenerate. Every
  // smoothed point still stays within the search radius of the line.
  std::mt19937 rng(9);
  std::normal_distribution<float> jitter(0.0f, 1e-7f);
  XyzCloud cloud;
  for (int i = 0; i < 400; ++i) cloud.push_back(pcl::PointXYZ(0.005f * i, jitter(rng), 1.0f + jitter(rng)));
  SmoothingParams params;
  const XyzCloud::Ptr smoothed = smooth(cloud, params);
  ASSERT_FALSE(smoothed->empty());
  for (const auto& p : *smoothed) {
    EXPECT_LT(std::hypot(p.y, p.z - 1.0f), params.radius) << p.x << " " << p.y << " " << p.z;
  }
}

TEST(Smooth, MatchesPclMovingLeastSquares) {
  // A noisy curved patch at the scene's scale (1 cm spacing, 2 mm noise).
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.0f, 0.002f);
  XyzCloud cloud;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 40; ++j) {
      const float x = 0.01f * i, y = 0.01f * j;
      cloud.push_back(pcl::PointXYZ(x, y, 1.0f + 0.5f * (x - 0.2f) * (x - 0.2f) + noise(rng)));
    }
  }
  SmoothingParams params;
  const XyzCloud ours = *smooth(cloud, params);
  pcl::MovingLeastSquares<pcl::PointXYZ, pcl::PointXYZ> mls;
  mls.setInputCloud(XyzCloud::ConstPtr(new XyzCloud(cloud)));
  mls.setSearchRadius(params.radius);
  mls.setPolynomialOrder(params.polynomial_order);
  XyzCloud theirs;
  mls.process(theirs);
  ASSERT_EQ(ours.size(), theirs.size());
  double moved = 0;
  for (size_t i = 0; i < ours.size(); ++i) {
    // PCL's k-d tree keeps neighbours strictly inside the radius, the grid includes it: a point
    // exactly on the sphere can change a fit by a hair, never more.
    EXPECT_LT((ours[i].getVector3fMap() - theirs[i].getVector3fMap()).norm(), 2e-4f) << i;
    moved += (ours[i].getVector3fMap() - cloud[i].getVector3fMap()).norm();
  }
  EXPECT_GT(moved / ours.size(), 5e-4);  // it did smooth: the noise is 2 mm
  testing::expectError(
      [&] {
        SmoothingParams bad;
        bad.polynomial_order = 9;
        smooth(cloud, bad);
      },
      ErrorCode::kInvalidInput, "polynomial_order");
}

}  // namespace
}  // namespace ism
