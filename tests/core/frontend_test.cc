#include "core/frontend/frontend.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <random>
#include <set>

#include "core/common/error.h"
#include "core/io/cloud_io.h"

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

// Expects `call` to throw ism::Error with `code` and a message containing `needle`.
template <class Call>
void expectError(Call call, ErrorCode code, const std::string& needle) {
  try {
    call();
    ADD_FAILURE() << "no error thrown; expected one mentioning '" << needle << "'";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

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

// A box (front face at 1.5 m, 40 x 30 cm) in front of a wall at 2 m, seen by a 160x120 camera.
Scene boxInFrontOfWall() {
  DepthIntrinsics intrinsics;
  intrinsics.fx = intrinsics.fy = 131.25f;  // Kinect's 525 px scaled to a quarter of the size
  intrinsics.cx = 79.5f;
  intrinsics.cy = 59.5f;
  std::vector<uint16_t> depth(160 * 120);
  for (int v = 0; v < 120; ++v) {
    for (int u = 0; u < 160; ++u) {
      const float x = (u - intrinsics.cx) / intrinsics.fx * 1.5f, y = (v - intrinsics.cy) / intrinsics.fy * 1.5f;
      depth[v * 160 + u] = std::abs(x) < 0.2f && std::abs(y) < 0.15f ? 1500 : 2000;
    }
  }
  return depthToScene(depth.data(), 160, 120, intrinsics, "box scene");
}

TEST(ExtractFeatures, BoxSceneKeypointsLieOnDepthEdgesAndStagesAreTimed) {
  const Scene scene = boxInFrontOfWall();
  StageTimings timings;
  const FrontEndResult result = extractFeatures(scene, FrontEndParams{}, /*apply_smoothing=*/true, &timings);
  std::vector<std::string> names;
  for (const auto& stage : timings.stages) names.push_back(stage.first);
  EXPECT_EQ(names, (std::vector<std::string>{"downsample", "smooth", "normals", "keypoints", "describe"}));
  EXPECT_EQ(result.input_points, scene.cloud->size());
  EXPECT_GE(result.keypoint_candidates, result.features.size());
  ASSERT_GT(result.features.size(), 50u);
  expectUnitDescriptorsAndRotationFrames(result.features);
  // Every keypoint is within 4 cm of an edge: the box outline, the outline of its shadow on the
  // wall, or the image border (on the wall).
  const auto distance_to_rectangle_edge = [](const Eigen::Vector3f& p, float half_w, float half_h) {
    const float dx = std::abs(std::abs(p.x()) - half_w), dy = std::abs(std::abs(p.y()) - half_h);
    const bool within_x = std::abs(p.x()) <= half_w + 0.04f, within_y = std::abs(p.y()) <= half_h + 0.04f;
    return std::min(within_y ? dx : 1e9f, within_x ? dy : 1e9f);
  };
  for (const auto& p : result.features.positions) {
    float distance;
    if (p.z() < 1.75f) {
      distance = distance_to_rectangle_edge(p, 0.2f, 0.15f);
    } else {
      const float image_half_w = 80.0f / 131.25f * 2.0f, image_half_h = 60.0f / 131.25f * 2.0f;
      distance = std::min(distance_to_rectangle_edge(p, 0.2f * 2 / 1.5f, 0.15f * 2 / 1.5f),
                          distance_to_rectangle_edge(p, image_half_w, image_half_h));
    }
    EXPECT_LT(distance, 0.04f) << "keypoint far from any edge: " << p.transpose();
  }
}

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
  std::cout << "tum_desk: " << result.input_points << " points -> " << result.surface->size() << " surface -> "
            << result.keypoint_candidates << " boundary -> " << result.features.size() << " features;";
  for (const auto& stage : timings.stages) std::cout << " " << stage.first << " " << stage.second << " ms";
  std::cout << "; total " << timings.total() << " ms\n";
  EXPECT_GT(result.surface->size(), 10000u);
  EXPECT_GT(result.features.size(), 1000u);
  EXPECT_LT(result.features.size(), result.surface->size() / 2);
  expectUnitDescriptorsAndRotationFrames(result.features);
}

}  // namespace
}  // namespace ism
