#include "core/frontend/smoothing.h"

#include <gtest/gtest.h>
#include <pcl/surface/mls.h>

#include <cmath>
#include <random>

#include "tests/common/expect_error.h"

namespace ism {
namespace {

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
