#include "core/frontend/occluding_contours.h"

#include <gtest/gtest.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <limits>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "core/frontend/frontend.h"
#include "core/io/cloud_io.h"
#include "tests/common/expect_error.h"
#include "tests/common/frontend_scenes.h"

namespace ism {
namespace {

using testing::boxInFrontOfWall;
using testing::boxOnFloorBeforeWall;
using testing::distanceToBox;
using testing::expectError;
using testing::kBoxCols;
using testing::kBoxHalf;
using testing::kBoxHeight;
using testing::kBoxRows;
using testing::kHeight;
using testing::kVoidColumn;
using testing::kWidth;
using testing::onBox;

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

}  // namespace
}  // namespace ism
