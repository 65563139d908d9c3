#include "core/frontend/frontend.h"

#include <gtest/gtest.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "core/gravity/viewpoint.h"
#include "core/io/cloud_io.h"
#include "tests/common/expect_error.h"
#include "tests/common/frontend_scenes.h"

namespace ism {
namespace {

using namespace ism::testing;

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

TEST(ExtractFeatures, BoxSceneKeypointsLieOnTheBoxOutlineAndStagesAreTimed) {
  const Scene scene = boxInFrontOfWall();
  StageTimings timings;
  const FrontEndResult result = extractFeatures(scene, FrontEndParams{}, /*apply_smoothing=*/true, &timings);
  std::vector<std::string> names;
  for (const auto& stage : timings.stages) names.push_back(stage.first);
  // An organized scene's keypoints come first: normals are computed only around them.
  EXPECT_EQ(names, (std::vector<std::string>{"downsample", "smooth", "gravity", "keypoints", "normals", "describe"}));
  // A model trained with `ism-train --no-scene-smoothing` stores this: scenes then skip MLS.
  FrontEndParams unsmoothed;
  unsmoothed.smoothing.enabled = false;
  StageTimings unsmoothed_timings;
  extractFeatures(scene, unsmoothed, /*apply_smoothing=*/true, &unsmoothed_timings);
  names.clear();
  for (const auto& stage : unsmoothed_timings.stages) names.push_back(stage.first);
  EXPECT_EQ(names, (std::vector<std::string>{"downsample", "gravity", "keypoints", "normals", "describe"}));
  // An unorganized cloud's range image has its contours before any normal, as a frame does; the
  // boundary test reads every point's normal.
  Scene unorganized = scene;
  unorganized.pixel_index.clear();
  StageTimings range_timings;
  const FrontEndResult ranged = extractFeatures(unorganized, unsmoothed, /*apply_smoothing=*/true, &range_timings);
  names.clear();
  for (const auto& stage : range_timings.stages) names.push_back(stage.first);
  EXPECT_EQ(names, (std::vector<std::string>{"downsample", "gravity", "keypoints", "normals", "describe"}));
  EXPECT_GT(ranged.features.size(), 0u);
  unsmoothed.keypoints.unorganized = KeypointMethod::kBoundary;
  StageTimings boundary_timings;
  extractFeatures(unorganized, unsmoothed, /*apply_smoothing=*/true, &boundary_timings);
  names.clear();
  for (const auto& stage : boundary_timings.stages) names.push_back(stage.first);
  EXPECT_EQ(names, (std::vector<std::string>{"downsample", "gravity", "normals", "keypoints", "describe"}));
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

TEST(ExtractFeatures, SurfaceKeypointsAddTheBoxsFacesButNeverTheFloorOrTheWall) {
  // Without noise: the Kinect's noise scatters a wall 4 m away over layers 5 cm apart, beyond the plane's
  // tolerance; keypoints_test checks how the samples keep clear of such points.
  const Scene scene = boxOnFloorBeforeWall(/*sensor_noise=*/false).scene;
  Scene unorganized = scene;
  unorganized.pixel_index.clear();
  unorganized.image_width = unorganized.image_height = 0;
  FrontEndParams contours;
  contours.smoothing.enabled = false;
  FrontEndParams sampled = contours;
  sampled.keypoints.surface_spacing = 0.09f;
  FrontEndParams boundary = contours, boundary_sampled = sampled;
  boundary.keypoints.unorganized = boundary_sampled.keypoints.unorganized = KeypointMethod::kBoundary;
  for (const Scene* input : std::vector<const Scene*>{&scene, &unorganized}) {
    for (const auto& [without, with] : {std::pair{contours, sampled}, std::pair{boundary, boundary_sampled}}) {
      const FrontEndResult plain = extractFeatures(*input, without, /*apply_smoothing=*/false);
      const FrontEndResult result = extractFeatures(*input, with, /*apply_smoothing=*/false);
      ASSERT_TRUE(result.gravity && result.gravity->hasFloor());
      // The 50 x 50 x 60 cm box's faces in view hold about 1.2 m^2 / (9 cm)^2 = 15 cubes more.
      EXPECT_GE(result.features.size(), plain.features.size() + 8) << input->source;
      // Floor and wall points stay in the descriptors' support but are never keypoints: every
      // keypoint lies on the box, between the floor and its top.
      for (const auto& p : result.features.positions) {
        const float height = result.gravity->height(p);
        EXPECT_GT(height, 0.015f) << "keypoint on the floor: " << p.transpose();
        EXPECT_LT(height, kBoxHeight + 0.05f) << "keypoint on the wall: " << p.transpose();
      }
    }
  }
}

// A face sampled every `spacing` metres from `corner` along `a` and `b`.
void addFace(Cloud& cloud, const Eigen::Vector3f& corner, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
             float spacing) {
  for (float s = 0; s <= a.norm(); s += spacing) {
    for (float t = 0; t <= b.norm(); t += spacing) {
      PointT p;
      p.getVector3fMap() = corner + a.normalized() * s + b.normalized() * t;
      cloud.push_back(p);
    }
  }
}

size_t walls(const Scene& scene, float max_seen_through) {
  FrontEndParams params;
  params.smoothing.enabled = false;
  params.gravity.wall_max_seen_through = max_seen_through;
  const FrontEndResult result = extractFeatures(scene, params, /*apply_smoothing=*/false);
  return result.gravity ? static_cast<size_t>(result.gravity->walls) : 0u;
}

TEST(ExtractFeatures, OnlyPlanesASensorSawThroughAreNoWalls) {
  // gravity_test's five boards in line before a wall, the wall showing between them. Seen from a
  // camera, a single view: with wall_max_seen_through set, their plane is no wall.
  Scene view;
  view.source = "single view";
  addFace(*view.cloud, {-3, -1, 0}, {6, 0, 0}, {0, 4, 0}, 0.03f);
  addFace(*view.cloud, {-3, 3, 0}, {6, 0, 0}, {0, 0, 2.5f}, 0.03f);
  for (float x : {-1.2f, -0.6f, 0.0f, 0.6f, 1.2f}) addFace(*view.cloud, {x - 0.05f, 0.5f, 0.05f}, {0.1f, 0, 0}, {0, 0, 1.1f}, 0.03f);
  view.sensor_origin = Eigen::Vector3f(0, -3, 1.5f);
  view.up = Eigen::Vector3f::UnitZ();
  EXPECT_EQ(walls(view, 0.0f), 2u);
  EXPECT_EQ(walls(view, 1.0f), 1u);
  // The same room closed all round, a map whose viewpoint is made up (viewpoint.h): nothing was
  // seen from there, so the test is not made and the boards' plane stays a wall.
  Scene map = view;
  map.source = "map";
  map.cloud.reset(new Cloud(*view.cloud));
  // (Sparser: else the boards' plane holds too few of the points to be looked at as a wall.)
  addFace(*map.cloud, {-3, -4, 0}, {6, 0, 0}, {0, 3, 0}, 0.06f);
  addFace(*map.cloud, {-3, -4, 0}, {6, 0, 0}, {0, 0, 2.5f}, 0.06f);
  addFace(*map.cloud, {-3, -4, 0}, {0, 7, 0}, {0, 0, 2.5f}, 0.06f);
  addFace(*map.cloud, {3, -4, 0}, {0, 7, 0}, {0, 0, 2.5f}, 0.06f);
  map.sensor_origin = Eigen::Vector3f(0, -1.5f, 1.5f);
  ASSERT_TRUE(surrounds(*map.cloud, map.sensor_origin));
  ASSERT_FALSE(surrounds(*view.cloud, view.sensor_origin));
  EXPECT_EQ(walls(map, 0.0f), 5u);
  EXPECT_EQ(walls(map, 1.0f), 5u);
}

// extractFeatures computes an organized scene's normals only near its keypoints; the features
// must be exactly those of the stages run on every point's normal. (Without the gravity stage,
// which only takes keypoints away: the stages below do not.)
void expectFeaturesOfTheFullSurface(const Scene& scene, FrontEndParams params) {
  params.gravity.enabled = false;
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

}  // namespace
}  // namespace ism
