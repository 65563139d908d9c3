#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <set>
#include <tuple>
#include <vector>

#include "core/common/error.h"
#include "core/io/depth_png.h"
#include "core/io/file_bytes.h"
#include "core/scanner/scanner.h"
#include "tests/common/synthetic_furniture.h"

namespace ism {
namespace {

using testing::boxMesh;
using testing::syntheticFurniture;

// The files writeTemp wrote, removed when the test binary exits.
struct TempFiles {
  std::vector<std::string> paths;
  ~TempFiles() {
    for (const auto& path : paths) std::remove(path.c_str());
  }
};

std::string writeTemp(const std::string& name, const std::string& content) {
  static TempFiles written;
  const std::string path = ::testing::TempDir() + "ism_scanner_" + std::to_string(getpid()) + "_" + name;
  std::ofstream(path, std::ios::binary) << content;
  written.paths.push_back(path);
  return path;
}

// Runs `load` and returns the ism::Error it throws (fails the test if it does not throw).
template <typename F>
Error errorOf(F load) {
  try {
    load();
  } catch (const Error& e) {
    return e;
  }
  ADD_FAILURE() << "expected ism::Error";
  return Error(ErrorCode::kInternal, "");
}

NoiseParams exactDepth() {
  NoiseParams noise;
  noise.enabled = false;
  return noise;
}

// A 6 x 6 m wall facing the camera at `distance` along +y, camera at the origin.
struct WallShot {
  Mesh wall = boxMesh({-3, 0, -3}, {3, 0, 3});
  Eigen::Isometry3f camera = lookAt({0, 0, 0}, {0, 1, 0});
  explicit WallShot(float distance) { wall = transformed(wall, Eigen::Isometry3f(Eigen::Translation3f(0, distance, 0))); }
};

double patchStdDev(const DepthImage& image, int half, double* mean_out) {
  const CameraIntrinsics& k = image.intrinsics;
  double sum = 0, sum_sq = 0;
  int n = 0;
  for (int row = k.height / 2 - half; row < k.height / 2 + half; ++row) {
    for (int col = k.width / 2 - half; col < k.width / 2 + half; ++col) {
      const double z = image.depth[row * k.width + col];
      sum += z;
      sum_sq += z * z;
      ++n;
    }
  }
  *mean_out = sum / n;
  return std::sqrt(sum_sq / n - *mean_out * *mean_out);
}

TEST(LoadMesh, ObjPolygonsOfAnySizeNegativeIndicesAndAttributes) {
  const std::string path = writeTemp("poly.obj",
                                     "# exported\nmtllib x.mtl\no thing\ng part\nusemtl wood\n"
                                     "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\ns off\n"
                                     "f 1/1/1 2/1/1 3/1/1 4/1/1\n"
                                     "v 0 0 1\nv 1 0 1\nv 1.5 0.5 1\nv 1 1 1\nv 0 1 1\r\n"
                                     "f -5 -4 -3 -2 -1\r\n"
                                     "f 1//1 2//1 5//1\n"
                                     "f 1 2\n");  // an edge written as a face: no area, skipped
  const Mesh mesh = loadMesh(path);
  ASSERT_EQ(mesh.vertices.size(), 9u);
  ASSERT_EQ(mesh.triangles.size(), 2u + 3u + 1u);
  EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(0, 2, 3));
  EXPECT_EQ(mesh.triangles[2], Eigen::Vector3i(4, 5, 6));  // -5 is the first of the five new vertices
  EXPECT_EQ(mesh.triangles[4], Eigen::Vector3i(4, 7, 8));
  EXPECT_EQ(mesh.triangles[5], Eigen::Vector3i(0, 1, 4));
  EXPECT_FLOAT_EQ(mesh.vertices[6].x(), 1.5f);
}

TEST(LoadMesh, ErrorsNameTheFileAndTheLine) {
  const std::string bad = writeTemp("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
  Error e = errorOf([&] { loadMesh(bad); });
  EXPECT_EQ(e.code(), ErrorCode::kInvalidInput);
  EXPECT_NE(std::string(e.what()).find(bad + " line 4"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("'7'"), std::string::npos) << e.what();

  const std::string short_vertex = writeTemp("short.obj", "v 0 0\n");
  e = errorOf([&] { loadMesh(short_vertex); });
  EXPECT_NE(std::string(e.what()).find(short_vertex + " line 1"), std::string::npos) << e.what();

  const std::string no_faces = writeTemp("nofaces.obj", "v 0 0 0\n");
  e = errorOf([&] { loadMesh(no_faces); });
  EXPECT_NE(std::string(e.what()).find("no faces"), std::string::npos) << e.what();

  const std::string missing = ::testing::TempDir() + "ism_scanner_does_not_exist.obj";
  e = errorOf([&] { loadMesh(missing); });
  EXPECT_EQ(e.code(), ErrorCode::kNotFound);
  EXPECT_NE(std::string(e.what()).find(missing), std::string::npos);

  e = errorOf([&] { loadMesh(writeTemp("mesh.stl", "solid x\n")); });
  EXPECT_EQ(e.code(), ErrorCode::kInvalidInput);
  EXPECT_NE(std::string(e.what()).find(".stl"), std::string::npos);

  const std::string bad_off = writeTemp("bad.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
  e = errorOf([&] { loadMesh(bad_off); });
  EXPECT_NE(std::string(e.what()).find(bad_off + " line 6"), std::string::npos) << e.what();
}

TEST(LoadMesh, OffCubeWithQuadsAndComments) {
  const std::string cube =
      "8 6 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
      "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7 255 0 0\n";
  const Mesh separate = loadMesh(writeTemp("cube.off", "OFF\n# a cube\n" + cube));
  EXPECT_EQ(separate.vertices.size(), 8u);
  EXPECT_EQ(separate.triangles.size(), 12u);
  EXPECT_EQ(separate.bounds().sizes(), Eigen::Vector3f::Ones());
  const Mesh same_line = loadMesh(writeTemp("cube2.off", "OFF " + cube));
  EXPECT_EQ(same_line.triangles.size(), 12u);
}

std::string plyBinary(bool little_endian) {
  std::string out = std::string("ply\nformat ") + (little_endian ? "binary_little_endian" : "binary_big_endian") +
                    " 1.0\ncomment test\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                    "property uchar red\nelement face 1\nproperty list uchar int vertex_indices\n"
                    "element edge 1\nproperty int a\nproperty int b\nend_header\n";
  auto append = [&](const void* value, size_t size) {
    char bytes[8];
    std::memcpy(bytes, value, size);
    if (!little_endian) std::reverse(bytes, bytes + size);
    out.append(bytes, size);
  };
  const float xyz[4][3] = {{0, 0, 0}, {2, 0, 0}, {2, 3, 0}, {0, 3, 0.5f}};
  for (const auto& v : xyz) {
    for (float c : v) append(&c, 4);
    out.push_back('\x7f');
  }
  out.push_back('\x04');
  for (int i : {0, 1, 2, 3}) append(&i, 4);
  for (int i : {0, 1}) append(&i, 4);
  return out;
}

TEST(LoadMesh, PlyAsciiAndBinaryOfBothByteOrders) {
  const Mesh ascii = loadMesh(writeTemp(
      "ascii.ply",
      "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty double x\r\nproperty double y\r\nproperty double z\r\n"
      "element face 1\r\nproperty list uchar uint vertex_index\r\nend_header\r\n0 0 0\r\n1 0 0\r\n0 1 2.5\r\n3 0 1 2\r\n"));
  EXPECT_EQ(ascii.triangles.size(), 1u);
  EXPECT_FLOAT_EQ(ascii.vertices[2].z(), 2.5f);
  for (bool little : {true, false}) {
    const Mesh mesh = loadMesh(writeTemp(little ? "le.ply" : "be.ply", plyBinary(little)));
    ASSERT_EQ(mesh.vertices.size(), 4u) << little;
    EXPECT_EQ(mesh.triangles.size(), 2u);
    EXPECT_EQ(mesh.vertices[3], Eigen::Vector3f(0, 3, 0.5f));
  }
  std::string truncated = plyBinary(true);
  truncated.resize(truncated.size() - 12);
  const std::string path = writeTemp("truncated.ply", truncated);
  const Error e = errorOf([&] { loadMesh(path); });
  EXPECT_NE(std::string(e.what()).find(path), std::string::npos);
  EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
}

TEST(PlaceMesh, RealSizeZUpCentredOnTheFloor) {
  const Mesh y_up = boxMesh({-1, 2, 5}, {1, 5, 6});  // width 2, height 3 (y), depth 1 (z)
  MeshPlacement placement;
  placement.size = {0.4f, 0.5f, 0.9f};
  Eigen::AlignedBox3f box = placeMesh(y_up, placement).bounds();
  EXPECT_TRUE(box.sizes().isApprox(Eigen::Vector3f(0.4f, 0.5f, 0.9f), 1e-5f)) << box.sizes().transpose();
  EXPECT_NEAR(box.min().z(), 0, 1e-6);
  EXPECT_NEAR(box.center().x(), 0, 1e-6);
  EXPECT_NEAR(box.center().y(), 0, 1e-6);

  // Uniform with all three sizes: one factor, the geometric mean of the three ratios, the longer
  // side of the footprint (2) against the longer given one (0.5): cbrt(0.25 * 0.4 * 0.3).
  placement.uniform = true;
  box = placeMesh(y_up, placement).bounds();
  const float fit = std::cbrt(0.25f * 0.4f * 0.3f);
  EXPECT_TRUE(box.sizes().isApprox(Eigen::Vector3f(2, 1, 3) * fit, 1e-5f)) << box.sizes().transpose();

  placement.size = {0.0f, 0.0f, 0.9f};  // uniform with the height alone: 3 -> 0.9 is 0.3 for all axes
  box = placeMesh(y_up, placement).bounds();
  EXPECT_TRUE(box.sizes().isApprox(Eigen::Vector3f(0.6f, 0.3f, 0.9f), 1e-5f)) << box.sizes().transpose();

  placement.uniform = false;  // missing depth: the mean of the other two factors (0.2, 0.3)
  placement.size = {0.4f, 0.0f, 0.9f};
  EXPECT_NEAR(placeMesh(y_up, placement).bounds().sizes().y(), 0.25f, 1e-5);

  // Orientation: Y-up "top" goes to +z, the model's front (+z) faces -y; a Sweet Home 3D
  // modelRotation of 180 deg about y turns the front to +y.
  Mesh marker;
  marker.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  marker.triangles = {{0, 1, 2}, {0, 2, 3}};
  Mesh placed = placeMesh(marker, MeshPlacement{});
  EXPECT_FLOAT_EQ(placed.vertices[2].z(), placed.bounds().max().z());
  EXPECT_FLOAT_EQ(placed.vertices[3].y(), placed.bounds().min().y());
  MeshPlacement turned;
  turned.pre_rotation << -1, 0, 0, 0, 1, 0, 0, 0, -1;
  placed = placeMesh(marker, turned);
  EXPECT_FLOAT_EQ(placed.vertices[3].y(), placed.bounds().max().y());

  MeshPlacement flat_z;
  flat_z.up = UpAxis::kZ;
  flat_z.size = {1, 1, 1};
  EXPECT_THROW(placeMesh(boxMesh({0, 0, 0}, {1, 1, 0}), flat_z), Error);
}

TEST(RenderDepth, WallAtKnownDistanceGivesExactDepthAndBackProjects) {
  const WallShot shot(2.0f);
  const DepthImage image = renderDepth({&shot.wall}, shot.camera, CameraIntrinsics{}, exactDepth());
  const int centre = 240 * 640 + 320;
  EXPECT_NEAR(image.depth[centre], 2.0f, 1e-5f);
  EXPECT_NEAR(image.depth[239 * 640 + 319], 2.0f, 1e-5f);

  const Scene scene = depthImageToWorldScene(image, "wall");
  ASSERT_EQ(scene.cloud->size(), 640u * 480u);  // the wall fills the view
  ASSERT_EQ(scene.pixel_index[centre], centre);
  // Pixel (320, 240) is half a pixel right of and below the optical axis (cx = 319.5).
  const Eigen::Vector3f expected(0.5f * 2 / 525, 2, -0.5f * 2 / 525);
  EXPECT_LT((scene.cloud->points[centre].getVector3fMap() - expected).norm(), 1e-5f);
  EXPECT_LT(scene.sensor_origin.norm(), 1e-6f);
  EXPECT_TRUE(scene.sensor_orientation.toRotationMatrix().isApprox(shot.camera.linear(), 1e-6f));
  EXPECT_EQ(scene.image_width, 640);
}

TEST(RenderDepth, ObliqueFloorDepthIsPerspectiveCorrect) {
  const Mesh floor = boxMesh({-20, -20, 0}, {20, 20, 0});
  const Eigen::Isometry3f camera = lookAt({0.3f, -3, 1.2f}, {0, 0, 0.4f});
  NoiseParams noise = exactDepth();
  noise.max_depth = 100;
  const CameraIntrinsics k;
  const DepthImage image = renderDepth({&floor}, camera, k, noise);
  int checked = 0;
  for (int row = 0; row < k.height; row += 7) {
    for (int col = 0; col < k.width; col += 7) {
      const Eigen::Vector3f ray = camera.linear() * Eigen::Vector3f((col - k.cx) / k.fx, (row - k.cy) / k.fy, 1);
      // `ray` has camera-frame z = 1, so the hit's ray parameter is its depth.
      const float expected = ray.z() < -1e-3f ? -1.2f / ray.z() : 0.0f;
      const Eigen::Vector3f hit = camera.translation() + expected * ray;
      if (hit.head<2>().cwiseAbs().maxCoeff() > 19) continue;  // near the floor's far edge
      ASSERT_NEAR(image.depth[row * k.width + col], expected, 1e-5f * (1 + expected)) << row << "," << col;
      checked += expected > 0;
    }
  }
  EXPECT_GT(checked, 2000);
}

TEST(RenderDepth, NoiseAtTwoMetresMatchesTheModelAndIsQuantised) {
  const WallShot shot(2.0f);
  NoiseParams noise;
  const double sigma = noise.sigma_a + noise.sigma_b * (2.0 - 0.4) * (2.0 - 0.4);
  double mean = 0;

  NoiseParams gaussian_only = noise;
  gaussian_only.disparity_step = 0;
  const double std_gaussian = patchStdDev(renderDepth({&shot.wall}, shot.camera, {}, gaussian_only), 100, &mean);
  EXPECT_NEAR(std_gaussian, sigma, 0.03 * sigma);
  EXPECT_NEAR(mean, 2.0, 2e-4);

  const DepthImage image = renderDepth({&shot.wall}, shot.camera, {}, noise);
  const double std_quantised = patchStdDev(image, 100, &mean);
  // Quantisation adds about step^2/12 of variance (Sheppard); the step at 2 m is ~1.27 cm.
  const double step = 2.0 * 2.0 * noise.disparity_step / (525.0 * noise.baseline);
  EXPECT_GT(std_quantised, 0.9 * sigma);
  EXPECT_LT(std_quantised, 1.2 * std::sqrt(sigma * sigma + step * step / 12));
  EXPECT_NEAR(mean, 2.0, 2e-3);
  RecordProperty("std_gaussian_mm", std::to_string(1000 * std_gaussian));
  RecordProperty("std_quantised_mm", std::to_string(1000 * std_quantised));
  std::set<float> levels;
  for (float z : image.depth) {
    const double steps = 525.0 * noise.baseline / z / noise.disparity_step;
    ASSERT_NEAR(steps, std::round(steps), 1e-3) << z;
    levels.insert(z);
  }
  EXPECT_GE(levels.size(), 3u);
  EXPECT_LE(levels.size(), 12u);

  noise.max_depth = 1.5f;  // the wall is beyond the sensor's range
  const DepthImage out_of_range = renderDepth({&shot.wall}, shot.camera, {}, noise);
  EXPECT_EQ(std::count(out_of_range.depth.begin(), out_of_range.depth.end(), 0.0f), 640 * 480);
}

TEST(RenderDepth, SameSeedGivesTheSameImage) {
  const WallShot shot(2.5f);
  NoiseParams noise;
  noise.seed = 7;
  const DepthImage a = renderDepth({&shot.wall}, shot.camera, {}, noise);
  const DepthImage b = renderDepth({&shot.wall}, shot.camera, {}, noise);
  EXPECT_EQ(a.depth, b.depth);
  noise.seed = 8;
  EXPECT_NE(renderDepth({&shot.wall}, shot.camera, {}, noise).depth, a.depth);
}

TEST(RenderDepth, TwentyThousandTriangleSphereGivesItsNearestDepth) {
  Mesh sphere;  // UV sphere, 100 x 100 quads = 20k triangles, 1 m across
  const int n = 100;
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      const float theta = static_cast<float>(M_PI) * i / n, phi = 2 * static_cast<float>(M_PI) * j / n;
      sphere.vertices.emplace_back(0.5f * std::sin(theta) * std::cos(phi), 2 + 0.5f * std::sin(theta) * std::sin(phi),
                                   0.5f * std::cos(theta));
    }
  }
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const int a = i * (n + 1) + j, b = a + n + 1;
      sphere.triangles.emplace_back(a, b, a + 1);
      sphere.triangles.emplace_back(a + 1, b, b + 1);
    }
  }
  const Eigen::Isometry3f camera = lookAt({0, 0, 0}, {0, 1, 0});
  const DepthImage image = renderDepth({&sphere}, camera, {}, NoiseParams{});
  EXPECT_NEAR(image.depth[240 * 640 + 320], 1.5f, 0.02f);
}

TEST(RenderDepth, TheProjectorsShadowLeavesABandLeftOfAnOccluder) {
  // A post 1.5 m away before a wall at 3 m: the projector, 7.5 cm right of the camera, cannot
  // reach the wall just left of the post, fx * b * (1/1.5 - 1/3) = 13 pixels of it.
  const Mesh wall = boxMesh({-3, 3, -3}, {3, 3.1f, 3});
  const Mesh post = boxMesh({-0.1f, 1.5f, -3}, {0.1f, 1.6f, 3});
  const Eigen::Isometry3f camera = lookAt({0, 0, 0}, {0, 1, 0});
  NoiseParams exact;
  exact.sigma_a = exact.sigma_b = 0;
  exact.disparity_step = 0;
  const auto row = [&](const DepthImage& image) {
    std::vector<float> r(image.depth.begin() + 240 * 640, image.depth.begin() + 241 * 640);
    return r;
  };
  const auto lit = row(renderDepth({&wall, &post}, camera, {}, exact));
  NoiseParams no_shadow = exact;
  no_shadow.projector_shadow = false;
  const auto all = row(renderDepth({&wall, &post}, camera, {}, no_shadow));
  int post_left = 640, missing = 0, missing_right_of_post = 0;
  for (int c = 0; c < 640; ++c) {
    ASSERT_GT(all[static_cast<size_t>(c)], 0.0f) << "without the shadow every pixel returns";
    if (std::abs(all[static_cast<size_t>(c)] - 1.5f) < 0.01f) post_left = std::min(post_left, c);
  }
  for (int c = 0; c < 640; ++c) {
    if (lit[static_cast<size_t>(c)] > 0) continue;
    ++missing;
    if (c >= post_left) ++missing_right_of_post;
  }
  EXPECT_NEAR(missing, 13, 2);
  EXPECT_EQ(missing_right_of_post, 0);
  EXPECT_EQ(lit[static_cast<size_t>(post_left - 1)], 0.0f) << "the band touches the post";
}

TEST(RenderDepth, TheCorrelationWindowLosesThinRodsAndJitteredEdgesFollowTheSeed) {
  // Before a wall at 3 m, 2 m from the camera: a rod 1 cm wide (2.6 pixels) and a post 10 cm wide
  // (26 pixels). A 9 x 9 window on the rod sees mostly wall, so the rod returns nothing; the post
  // and the wall keep their pixels.
  const Mesh wall = boxMesh({-3, 3, -3}, {3, 3.1f, 3});
  const Mesh rod = boxMesh({-0.2f, 2.0f, -3}, {-0.19f, 2.01f, 3});
  const Mesh post = boxMesh({0.3f, 2.0f, -3}, {0.4f, 2.05f, 3});
  const Eigen::Isometry3f camera = lookAt({0, 0, 0}, {0, 1, 0});
  NoiseParams exact;
  exact.sigma_a = exact.sigma_b = 0;
  exact.disparity_step = 0;
  exact.projector_shadow = false;
  NoiseParams window = exact;
  window.window = 9;
  const auto near = [](const DepthImage& image, int row) {  // pixels of the row on the rod and on the post
    int rod = 0, post = 0, wall = 0;
    for (int c = 0; c < 640; ++c) {
      const float z = image.depth[static_cast<size_t>(row * 640 + c)];
      if (std::abs(z - 2.0f) < 0.01f) (c < 320 ? rod : post) += 1;
      if (std::abs(z - 3.0f) < 0.01f) ++wall;
    }
    return std::make_tuple(rod, post, wall);
  };
  const DepthImage plain = renderDepth({&wall, &rod, &post}, camera, {}, exact);
  const DepthImage windowed = renderDepth({&wall, &rod, &post}, camera, {}, window);
  const auto [rod0, post0, wall0] = near(plain, 240);
  const auto [rod1, post1, wall1] = near(windowed, 240);
  EXPECT_GE(rod0, 2);
  EXPECT_EQ(rod1, 0) << "a rod narrower than half the window returns nothing";
  EXPECT_NEAR(post1, post0, 2);
  EXPECT_NEAR(wall1, wall0, 6) << "the wall loses at most the pixels beside the rod";

  // Each pixel reading the depth half a pixel off: the post's edges move from row to row, the
  // same way for the same seed.
  NoiseParams shifted = exact;
  shifted.pixel_shift = 0.5f;
  const DepthImage a = renderDepth({&wall, &rod, &post}, camera, {}, shifted);
  std::set<int> widths;
  for (int row = 100; row < 380; row += 10) widths.insert(std::get<1>(near(a, row)));
  EXPECT_GE(widths.size(), 2u);
  for (int w : widths) EXPECT_NEAR(w, post0, 3);
  EXPECT_EQ(renderDepth({&wall, &rod, &post}, camera, {}, shifted).depth, a.depth);
}

TEST(SampleSurface, EvenlySpreadOnTheSurfaceDeterministicAndCapped) {
  const Mesh cube = testing::boxMesh({0, 0, 0}, {1, 1, 1});
  const auto points = sampleSurface(cube, 0.05f, 100000, 3);
  // Six faces of 1 m2 at one point per 5 cm cube: about 400 a face, fewer where cells are cut.
  EXPECT_GT(points.size(), 6u * 300u);
  EXPECT_LT(points.size(), 6u * 500u);
  std::set<std::tuple<int, int, int>> cells;
  for (const auto& p : points) {
    const Eigen::Vector3f d = p.cwiseMin(Eigen::Vector3f::Ones() - p);  // distances to the faces
    EXPECT_NEAR(d.minCoeff(), 0.0f, 1e-5f) << "on a face";
    EXPECT_TRUE(cells.emplace(static_cast<int>(std::floor(p.x() / 0.05f)), static_cast<int>(std::floor(p.y() / 0.05f)),
                              static_cast<int>(std::floor(p.z() / 0.05f))).second) << "one point per cube";
  }
  EXPECT_EQ(sampleSurface(cube, 0.05f, 100000, 3), points);
  const auto first = sampleSurface(cube, 0.05f, 50, 3);
  ASSERT_EQ(first.size(), 50u);
  Eigen::Vector3f mean = Eigen::Vector3f::Zero();
  for (const auto& p : first) mean += p / 50.0f;
  EXPECT_LT((mean - Eigen::Vector3f::Constant(0.5f)).norm(), 0.2f) << "a prefix spreads over the whole cube";
  EXPECT_THROW(sampleSurface(cube, 0.0f, 10), Error);
}

TEST(ViewRing, TwelveViewsAroundAndAboveEachSeeTheWholeObject) {
  const Mesh chair = syntheticFurniture("dining_chair", 0);
  const std::vector<Eigen::Isometry3f> poses = viewRing(chair, ViewRingParams{});
  ASSERT_EQ(poses.size(), 12u);
  const Eigen::AlignedBox3f box = chair.bounds();
  const CameraIntrinsics k;
  std::set<int> azimuths;
  for (const Eigen::Isometry3f& pose : poses) {
    const Eigen::Vector3f offset = pose.translation() - box.center();
    EXPECT_NEAR(std::asin(offset.z() / offset.norm()) * 180 / M_PI, 20.0, 1e-3);
    azimuths.insert(static_cast<int>(std::lround(std::atan2(offset.y(), offset.x()) * 180 / M_PI)));
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Vector3f p = pose.inverse() * box.corner(static_cast<Eigen::AlignedBox3f::CornerType>(corner));
      ASSERT_GT(p.z(), NoiseParams{}.min_depth);
      EXPECT_GT(k.fx * p.x() / p.z() + k.cx, 0);
      EXPECT_LT(k.fx * p.x() / p.z() + k.cx, k.width - 1);
      EXPECT_GT(k.fy * p.y() / p.z() + k.cy, 0);
      EXPECT_LT(k.fy * p.y() / p.z() + k.cy, k.height - 1);
    }
    const DepthImage image = renderDepth({&chair}, pose, k, NoiseParams{});
    EXPECT_GT(std::count_if(image.depth.begin(), image.depth.end(), [](float z) { return z > 0; }), 3000);
  }
  EXPECT_EQ(azimuths.size(), 12u);
  EXPECT_EQ(azimuths.count(-90), 1u);  // the first view faces the front (-y)
}

TEST(ViewRing, AMinimumDistanceMovesSmallObjectsOutAndLeavesLargeOnesWhole) {
  const Mesh chair = syntheticFurniture("dining_chair", 0);
  const float fitted = (viewRing(chair, ViewRingParams{}).front().translation() - chair.bounds().center()).norm();
  ViewRingParams far;
  far.min_distance = 3.5f;
  ASSERT_LT(fitted, far.min_distance);
  for (const Eigen::Isometry3f& pose : viewRing(chair, far)) {
    EXPECT_NEAR((pose.translation() - chair.bounds().center()).norm(), 3.5f, 1e-4f);
  }
  far.min_distance = 0.5f * fitted;  // nearer than the object fits in view: the fitted distance stands
  EXPECT_NEAR((viewRing(chair, far).front().translation() - chair.bounds().center()).norm(), fitted, 1e-4f);
  far.distance = 1.0f;  // a fixed distance wins over both
  EXPECT_NEAR((viewRing(chair, far).front().translation() - chair.bounds().center()).norm(), 1.0f, 1e-4f);
}

TEST(ComposeScene, GroundTruthMatchesTheMeshesAndLabelsThePoints) {
  std::vector<SceneObject> objects(2);
  objects[0] = {"dining_table", syntheticFurniture("dining_table", 0), 0.3f, 0.6f, 0.4f};
  objects[1] = {"office_chair", syntheticFurniture("office_chair", 2), -0.9f, -0.3f, 2.0f};
  SyntheticSceneParams params;
  params.noise.enabled = false;
  const SyntheticScene result = composeScene(objects, params);
  ASSERT_EQ(result.objects.size(), 2u);
  ASSERT_EQ(result.point_object.size(), result.scene.cloud->size());
  int floor_points = 0;
  std::vector<int> counted(2, 0);
  for (size_t i = 0; i < result.point_object.size(); ++i) {
    const Eigen::Vector3f p = result.scene.cloud->points[i].getVector3fMap();
    const int id = result.point_object[i];
    if (id < 0) {
      ASSERT_NEAR(p.z(), 0, 1e-3f);
      ++floor_points;
      continue;
    }
    ++counted[id];
    const GroundTruthObject& truth = result.objects[id];
    const Eigen::Vector3f local = Eigen::AngleAxisf(-truth.yaw, Eigen::Vector3f::UnitZ()) * (p - truth.center);
    ASSERT_TRUE(((local.cwiseAbs() - truth.size / 2).array() < 0.01f).all()) << id << ": " << local.transpose();
  }
  for (int id = 0; id < 2; ++id) {
    const GroundTruthObject& truth = result.objects[id];
    const Eigen::AlignedBox3f box = objects[id].mesh.bounds();
    EXPECT_EQ(truth.category, objects[id].category);
    EXPECT_TRUE(truth.size.isApprox(box.sizes(), 1e-6f));
    EXPECT_NEAR(truth.center.x(), objects[id].x, 1e-5f);  // placed meshes are centred on x = y = 0
    EXPECT_NEAR(truth.center.y(), objects[id].y, 1e-5f);
    EXPECT_NEAR(truth.center.z(), box.sizes().z() / 2, 1e-5f);
    EXPECT_EQ(truth.points, counted[id]);
    EXPECT_GT(truth.points, 2000);
  }
  EXPECT_GT(floor_points, 10000);
  EXPECT_TRUE(result.scene.sensor_origin.isApprox(params.camera_eye));
}

TEST(DepthPng, SavedDepthRoundTripsInMillimetres) {
  const WallShot shot(1.5f);
  const DepthImage image = renderDepth({&shot.wall}, shot.camera, {}, NoiseParams{});
  const std::string path = ::testing::TempDir() + "ism_scanner_" + std::to_string(getpid()) + "_depth.png";
  saveDepthPng(image, 1000.0f, path);
  const DepthPng png = decodeDepthPng16(readFileBytes(path), path);
  ASSERT_EQ(png.width, 640);
  ASSERT_EQ(png.height, 480);
  for (size_t i = 0; i < png.pixels.size(); i += 997) {
    ASSERT_EQ(png.pixels[i], static_cast<uint16_t>(std::lround(image.depth[i] * 1000))) << i;
  }
  EXPECT_THROW(saveDepthPng(image, 1e5f, path), Error);  // 1.5 m does not fit 16 bits at 10 um
  std::remove(path.c_str());
}

TEST(SyntheticFurniture, RealSizesAndDeterministicVariants) {
  const std::pair<const char*, Eigen::Vector3f> nominal[] = {{"dining_table", {1.2f, 0.8f, 0.75f}},
                                                             {"dining_chair", {0.45f, 0.5f, 0.9f}},
                                                             {"office_chair", {0.55f, 0.53f, 0.95f}},
                                                             {"couch", {1.9f, 0.85f, 0.8f}}};
  for (const auto& [category, size] : nominal) {
    const Mesh base = syntheticFurniture(category, 0);
    const Eigen::AlignedBox3f box = base.bounds();
    EXPECT_TRUE(((box.sizes() - size).cwiseAbs().array() < 0.05f * size.array()).all())
        << category << ": " << box.sizes().transpose();
    EXPECT_NEAR(box.min().z(), 0, 1e-6);
    EXPECT_NEAR(box.center().head<2>().norm(), 0, 1e-6);
    const Mesh variant = syntheticFurniture(category, 3);
    const Eigen::Vector3f ratio = variant.bounds().sizes().cwiseQuotient(box.sizes());
    EXPECT_FALSE(ratio.isApprox(Eigen::Vector3f::Ones(), 1e-3f)) << category;
    EXPECT_TRUE(((ratio.array() - 1).abs() < 0.06f).all()) << category << ": " << ratio.transpose();
    EXPECT_EQ(syntheticFurniture(category, 3).vertices, variant.vertices);
  }
  EXPECT_THROW(syntheticFurniture("bed", 0), Error);
}

}  // namespace
}  // namespace ism
