#include "core/frontend/neighbour_grid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <vector>

#include "tests/common/expect_error.h"
#include "tests/common/frontend_scenes.h"

namespace ism {
namespace {

using testing::randomSurfacePoints;

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

}  // namespace
}  // namespace ism
