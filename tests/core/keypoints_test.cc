#include "core/frontend/keypoints.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <set>
#include <vector>

#include "core/frontend/downsample.h"
#include "core/frontend/occluding_contours.h"
#include "tests/common/expect_error.h"
#include "tests/common/frontend_scenes.h"

namespace ism {
namespace {

using namespace ism::testing;

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

TEST(Keypoints, UnorganizedInputTakesTheChosenDetector) {
  const Scene organized = boxInFrontOfWall();
  Scene unorganized = organized;
  unorganized.pixel_index.clear();
  unorganized.image_width = unorganized.image_height = 0;
  KeypointParams automatic;
  EXPECT_EQ(resolveKeypointMethod(automatic, organized), KeypointMethod::kOccludingContour);
  EXPECT_EQ(resolveKeypointMethod(automatic, unorganized), KeypointMethod::kRangeImage);
  automatic.unorganized = KeypointMethod::kBoundary;
  EXPECT_EQ(resolveKeypointMethod(automatic, unorganized), KeypointMethod::kBoundary);
  KeypointParams boundary_only;
  boundary_only.method = KeypointMethod::kBoundary;
  EXPECT_EQ(resolveKeypointMethod(boundary_only, organized), KeypointMethod::kBoundary);

  FrontEndParams params;
  params.keypoints.unorganized = KeypointMethod::kBoundary;
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

// The same scene without its pixel grid: the range image seen from the sensor finds the box's
// silhouette again, and neither the wall's face nor the floor-less image border.
TEST(Keypoints, TheRangeImageOfAnUnorganizedCloudFindsTheOccludingContours) {
  const Scene organized = boxInFrontOfWall();
  Scene unorganized = organized;
  unorganized.pixel_index.clear();
  unorganized.image_width = unorganized.image_height = 0;
  const FrontEndParams params;
  const float leaf = params.downsample.leaf_size;
  const auto surface = estimateNormals(*downsample(*organized.cloud, params.downsample), params.normals,
                                       organized.sensor_origin);
  const std::vector<int> contour = detectKeypoints(organized, *surface, params.keypoints, leaf);
  const std::vector<int> ranged = detectKeypoints(unorganized, *surface, params.keypoints, leaf);
  ASSERT_FALSE(contour.empty());
  ASSERT_FALSE(ranged.empty());
  // Within one pixel of the range image (2.5 point spacings: 2.9 cm at the box's 1.5 m in this
  // 160 x 120 frame) and one voxel of the organized contour.
  constexpr float kNear = 0.04f;
  const auto nearContour = [&](int k) {
    for (int c : contour) {
      if (((*surface)[static_cast<size_t>(k)].getVector3fMap() - (*surface)[static_cast<size_t>(c)].getVector3fMap()).norm() <= kNear) {
        return true;
      }
    }
    return false;
  };
  const auto near = std::count_if(ranged.begin(), ranged.end(), nearContour);
  EXPECT_GE(near, static_cast<long>(0.9 * static_cast<double>(ranged.size())))
      << near << " of " << ranged.size() << " range-image keypoints lie near the organized contours";
  // Its pixels are 2.5 point spacings wide, so a contour is about 2.5 times fewer pixels long.
  EXPECT_GE(ranged.size(), contour.size() / 5) << "the range image finds too little of the silhouette";
  EXPECT_LT(ranged.size(), surface->size() / 10) << "the range image fires on faces, not only on contours";
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

TEST(Keypoints, SurfaceSamplesTakeThePointNearestEachCubesCentreAwayFromWhatIsNotEligible) {
  // 20 x 20 points at the centres of 1 cm voxels from (0.005, 0.005) on: 4 x 4 cubes of 5 cm, each
  // with a point at its centre's x and y, (i, j) = (2, 7, 12 or 17).
  const int n = 20;
  XyzCloud grid = gridPlane(n, 0.01f, 1.025f);
  for (auto& p : grid) p.x += 0.1f, p.y += 0.1f;
  std::vector<uint8_t> eligible(grid.size(), 1);
  std::vector<int> centres;
  for (int i : {2, 7, 12, 17}) {
    for (int j : {2, 7, 12, 17}) centres.push_back(i * n + j);
  }
  EXPECT_EQ(sampleSurfaceKeypoints(grid, eligible, {0.05f, 1, 0.0f}), centres);
  // Points that are not eligible (the floor, walls) are never taken: the first row of cubes has none.
  for (int k = 0; k < 5 * n; ++k) eligible[static_cast<size_t>(k)] = 0;
  const std::vector<int> rows_after_first(centres.begin() + 4, centres.end());
  EXPECT_EQ(sampleSurfaceKeypoints(grid, eligible, {0.05f, 1, 0.0f}), rows_after_first);
  // With a clearance, nor is a point that near them: the next row's centres lie 3 cm from row 4.
  EXPECT_EQ(sampleSurfaceKeypoints(grid, eligible, {0.05f, 1, 0.025f}), rows_after_first);
  EXPECT_EQ(sampleSurfaceKeypoints(grid, eligible, {0.05f, 1, 0.035f}),
            std::vector<int>(centres.begin() + 8, centres.end()));
  // A cube with fewer eligible points than min_points has none: the second row's first cube, with 24
  // of its 25 points eligible, is taken at a minimum of 24 and not at 25.
  eligible[static_cast<size_t>(5 * n)] = 0;
  EXPECT_EQ(sampleSurfaceKeypoints(grid, eligible, {0.05f, 25, 0.0f}),
            std::vector<int>(centres.begin() + 5, centres.end()));
  EXPECT_EQ(sampleSurfaceKeypoints(grid, eligible, {0.05f, 24, 0.0f}), rows_after_first);
  expectError([&] { sampleSurfaceKeypoints(grid, eligible, {0.0f, 1, 0.0f}); }, ErrorCode::kInvalidInput,
              "keypoints.surface_spacing");
  eligible.pop_back();
  expectError([&] { sampleSurfaceKeypoints(grid, eligible, {0.05f, 1, 0.0f}); }, ErrorCode::kInternal, "flags for");
}

}  // namespace
}  // namespace ism
