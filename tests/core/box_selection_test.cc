#include "core/recognition/box_selection.h"

#include <gtest/gtest.h>

#include <algorithm>

namespace ism {
namespace {

TEST(BoxSelection, FitsARotatedBoxAndAppliesTheLimits) {
  const Eigen::Matrix3f rotation = Eigen::AngleAxisf(0.7f, Eigen::Vector3f(0.2f, 0.3f, 1.0f).normalized()).toRotationMatrix();
  const Eigen::Vector3f center(2, 1, 0.4f), half(0.5f, 0.25f, 0.1f);
  std::vector<Eigen::Vector3f> corners;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3f s((i & 1) ? 1.f : -1.f, (i & 2) ? 1.f : -1.f, (i & 4) ? 1.f : -1.f);
    corners.push_back(center + rotation * s.cwiseProduct(half));
  }
  const OrientedBox box = fitOrientedBox(corners);
  EXPECT_LT((box.center - center).norm(), 1e-4f);
  Eigen::Vector3f size = box.size;
  std::sort(size.data(), size.data() + 3);
  EXPECT_TRUE(size.isApprox(Eigen::Vector3f(0.2f, 0.5f, 1.0f), 1e-4f)) << size.transpose();
  EXPECT_NEAR(box.volume(), 0.1f, 1e-4f);

  BoxStats stats{0.05f, 0.2f, 1.2f};
  EXPECT_TRUE(passesBoxSelection(box, stats));
  stats.max_edge = 0.9f;  // longest edge too long
  EXPECT_FALSE(passesBoxSelection(box, stats));
  stats = {0.15f, 0.2f, 1.2f};  // too small
  EXPECT_FALSE(passesBoxSelection(box, stats));
  stats = {0.01f, 0.05f, 1.2f};  // too large
  EXPECT_FALSE(passesBoxSelection(box, stats));
}

}  // namespace
}  // namespace ism
