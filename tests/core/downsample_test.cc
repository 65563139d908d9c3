#include "core/frontend/downsample.h"

#include <gtest/gtest.h>
#include <pcl/common/io.h>
#include <pcl/filters/voxel_grid.h>

#include <algorithm>
#include <limits>
#include <random>
#include <vector>

#include "tests/common/expect_error.h"

namespace ism {
namespace {

std::vector<Eigen::Vector3f> sortedPoints(const XyzCloud& cloud) {
  std::vector<Eigen::Vector3f> points;
  for (const auto& p : cloud) points.push_back(p.getVector3fMap());
  std::sort(points.begin(), points.end(), [](const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
  });
  return points;
}

using testing::expectError;

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

// The centroids come in pcl::VoxelGrid's order (ascending voxel index) with its values, on a cloud
// of many voxels and some points without a value.
TEST(Downsample, MatchesPclVoxelGridInItsOrder) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> coordinate(-0.5f, 0.7f);
  Cloud cloud;
  for (int i = 0; i < 30000; ++i) {
    PointT p;
    p.x = coordinate(rng), p.y = coordinate(rng), p.z = coordinate(rng);
    if (i % 97 == 0) p.y = std::numeric_limits<float>::quiet_NaN();
    cloud.push_back(p);
  }
  DownsampleParams params;
  params.leaf_size = 0.05f;
  const auto got = downsample(cloud, params);
  pcl::PointCloud<pcl::PointXYZ> xyz, expected;
  pcl::copyPointCloud(cloud, xyz);
  xyz.is_dense = false;
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(xyz.makeShared());
  grid.setLeafSize(params.leaf_size, params.leaf_size, params.leaf_size);
  grid.filter(expected);
  ASSERT_GT(expected.size(), 10000u);
  ASSERT_EQ(got->size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    ASSERT_LT(((*got)[i].getVector3fMap() - expected[i].getVector3fMap()).norm(), 1e-5f) << "centroid " << i;
  }
}

}  // namespace
}  // namespace ism
