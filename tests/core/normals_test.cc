#include "core/frontend/normals.h"

#include <gtest/gtest.h>
#include <pcl/features/normal_3d.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <numeric>
#include <tuple>

#include "core/frontend/downsample.h"
#include "core/frontend/keypoints.h"
#include "core/io/cloud_io.h"
#include "tests/common/frontend_scenes.h"

namespace ism {
namespace {

using testing::gridPlane;
using testing::randomSurfacePoints;

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

}  // namespace
}  // namespace ism
