#include "core/scanner/scanner.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <unordered_map>

#include "core/common/error.h"
#include "core/io/depth_png.h"
#include "core/io/file_bytes.h"

namespace ism {
namespace {

// Closer than this the projection degenerates; triangles are clipped against it.
constexpr float kNearPlane = 0.01f;

void checkIntrinsics(const CameraIntrinsics& k) {
  if (k.width <= 0 || k.height <= 0 || !(k.fx > 0) || !(k.fy > 0)) {
    throw Error(ErrorCode::kInvalidInput, "camera intrinsics: need width, height, fx, fy > 0, got " +
                                              std::to_string(k.width) + "x" + std::to_string(k.height) +
                                              " fx=" + std::to_string(k.fx) + " fy=" + std::to_string(k.fy));
  }
}

// Z-buffer over camera-frame triangles; depth is along the optical axis, like a Kinect's.
class Rasterizer {
 public:
  Rasterizer(const CameraIntrinsics& k, std::vector<float>* depth, std::vector<int>* label)
      : k_(k), depth_(*depth), label_(label) {}

  void drawClipped(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c, int id) {
    const Eigen::Vector3f in[3] = {a, b, c};
    Eigen::Vector3f out[4];
    int n = 0;
    for (int i = 0; i < 3; ++i) {  // Sutherland-Hodgman against z = near
      const Eigen::Vector3f& p = in[i];
      const Eigen::Vector3f& q = in[(i + 1) % 3];
      if (p.z() >= kNearPlane) out[n++] = p;
      if ((p.z() >= kNearPlane) != (q.z() >= kNearPlane)) {
        out[n++] = p + (q - p) * ((kNearPlane - p.z()) / (q.z() - p.z()));
      }
    }
    for (int i = 1; i + 1 < n; ++i) draw(out[0], out[i], out[i + 1], id);
  }

 private:
  void draw(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c, int id) {
    const Eigen::Vector3f* v[3] = {&a, &b, &c};
    double u[3], w[3];
    for (int i = 0; i < 3; ++i) {
      u[i] = static_cast<double>(k_.fx) * v[i]->x() / v[i]->z() + k_.cx;
      w[i] = static_cast<double>(k_.fy) * v[i]->y() / v[i]->z() + k_.cy;
    }
    const double area = (u[1] - u[0]) * (w[2] - w[0]) - (w[1] - w[0]) * (u[2] - u[0]);
    if (!(std::abs(area) > 1e-12)) return;  // edge-on or NaN
    // The triangle's plane n.X = d seen through pixel (col, row) gives 1/z affine in the image:
    // exact depth everywhere, not just at the vertices, and no error growing across big triangles.
    const Eigen::Vector3d p0 = a.cast<double>();
    const Eigen::Vector3d n = (b.cast<double>() - p0).cross(c.cast<double>() - p0);
    const double d = n.dot(p0);
    if (!(std::abs(d) > 1e-12 * n.norm())) return;  // plane through the camera
    const double inv_z_col = n.x() / (k_.fx * d);
    const double inv_z_row = n.y() / (k_.fy * d);
    const double inv_z_0 = n.z() / d - inv_z_col * k_.cx - inv_z_row * k_.cy;
    // Pixel (col, row) samples the image point (col, row): cx = 319.5 is the image centre.
    const int col0 = std::max(0, static_cast<int>(std::ceil(std::min({u[0], u[1], u[2]}))));
    const int col1 = std::min(k_.width - 1, static_cast<int>(std::floor(std::max({u[0], u[1], u[2]}))));
    const int row0 = std::max(0, static_cast<int>(std::ceil(std::min({w[0], w[1], w[2]}))));
    const int row1 = std::min(k_.height - 1, static_cast<int>(std::floor(std::max({w[0], w[1], w[2]}))));
    if (col0 > col1 || row0 > row1) return;
    // Barycentric weights as edge functions (opposite vertex i), stepped per pixel.
    const double s = 1.0 / area;
    double du[3], dw[3], e_row[3];
    for (int i = 0; i < 3; ++i) {
      const int j = (i + 1) % 3, l = (i + 2) % 3;
      du[i] = -(w[l] - w[j]) * s;
      dw[i] = (u[l] - u[j]) * s;
      e_row[i] = ((u[l] - u[j]) * (row0 - w[j]) - (w[l] - w[j]) * (col0 - u[j])) * s;
    }
    // Pixels on an edge shared by two triangles belong to both, so no cracks open between them.
    constexpr double kOnEdge = -1e-9;
    for (int row = row0; row <= row1; ++row) {
      double e[3] = {e_row[0], e_row[1], e_row[2]};
      float* depth_row = depth_.data() + static_cast<size_t>(row) * k_.width;
      for (int col = col0; col <= col1; ++col) {
        if (e[0] >= kOnEdge && e[1] >= kOnEdge && e[2] >= kOnEdge) {
          const float z = static_cast<float>(1.0 / (inv_z_0 + inv_z_col * col + inv_z_row * row));
          if (z > 0 && z < depth_row[col]) {
            depth_row[col] = z;
            if (label_ != nullptr) (*label_)[static_cast<size_t>(row) * k_.width + col] = id;
          }
        }
        for (int i = 0; i < 3; ++i) e[i] += du[i];
      }
      for (int i = 0; i < 3; ++i) e_row[i] += dw[i];
    }
  }

  const CameraIntrinsics& k_;
  std::vector<float>& depth_;
  std::vector<int>* label_;
};

// The correlation window's effects on the exact depth (NoiseParams::pixel_shift, window), in
// place; infinity = no return. `label` (may be null) follows the shifted pixels.
void applyCorrelationWindow(std::vector<float>* depth, std::vector<int>* label, const CameraIntrinsics& k,
                            const NoiseParams& noise) {
  const int w = k.width, h = k.height;
  const float inf = std::numeric_limits<float>::infinity();
  if (noise.pixel_shift > 0) {
    std::mt19937 rng(noise.seed ^ 0x9e3779b9u);
    std::normal_distribution<float> shift(0.0f, noise.pixel_shift);
    std::vector<float> shifted(depth->size(), inf);
    std::vector<int> shifted_label(label != nullptr ? label->size() : 0, -1);
    for (int row = 0; row < h; ++row) {
      for (int col = 0; col < w; ++col) {
        const long u = std::lround(static_cast<float>(col) + shift(rng));
        const long v = std::lround(static_cast<float>(row) + shift(rng));
        if (u < 0 || v < 0 || u >= w || v >= h) continue;
        const size_t from = static_cast<size_t>(v * w + u), to = static_cast<size_t>(row * w + col);
        shifted[to] = (*depth)[from];
        if (label != nullptr) shifted_label[to] = (*label)[from];
      }
    }
    depth->swap(shifted);
    if (label != nullptr) label->swap(shifted_label);
  }
  if (noise.window <= 1 || noise.window_agreement <= 0) return;
  const float fb = k.fx * noise.baseline;
  const int r = noise.window / 2;
  std::vector<float> kept(*depth);
  for (int row = 0; row < h; ++row) {
    for (int col = 0; col < w; ++col) {
      const float z = (*depth)[static_cast<size_t>(row * w + col)];
      if (!std::isfinite(z) || z <= 0) continue;
      const float d = fb / z;
      int samples = 0, agree = 0;
      for (int dv = -r; dv <= r; dv += 2) {
        const int v = row + dv;
        if (v < 0 || v >= h) continue;
        for (int du = -r; du <= r; du += 2) {
          const int u = col + du;
          if (u < 0 || u >= w) continue;
          ++samples;
          const float zz = (*depth)[static_cast<size_t>(v * w + u)];
          agree += std::isfinite(zz) && zz > 0 && std::abs(fb / zz - d) <= noise.window_tolerance;
        }
      }
      if (static_cast<float>(agree) < noise.window_agreement * static_cast<float>(samples)) kept[static_cast<size_t>(row * w + col)] = inf;
    }
  }
  depth->swap(kept);
}

// Kinect-like measurement of the exact depth, in place (0 = no return).
void applySensorModel(std::vector<float>* depth, const CameraIntrinsics& k, const NoiseParams& noise) {
  std::mt19937 rng(noise.seed);
  std::normal_distribution<float> gaussian(0.0f, 1.0f);
  const float fb = k.fx * noise.baseline;
  for (float& z : *depth) {
    if (!std::isfinite(z) || z < noise.min_depth || z > noise.max_depth) {
      z = 0.0f;
      continue;
    }
    if (!noise.enabled) continue;
    const float sigma = noise.sigma_a + noise.sigma_b * (z - 0.4f) * (z - 0.4f);
    float measured = z + sigma * gaussian(rng);
    if (noise.disparity_step > 0 && measured > 0) {
      const float disparity = std::round(fb / measured / noise.disparity_step) * noise.disparity_step;
      measured = disparity > 0 ? fb / disparity : 0.0f;
    }
    z = std::max(measured, 0.0f);
  }
}

// Clears the pixels of `depth` (exact, camera at camera_to_world) whose surface the projector, at
// (baseline, 0, 0) in the camera's frame, does not see: another surface lies before it from there.
void castProjectorShadow(const std::vector<const Mesh*>& meshes, const Eigen::Isometry3f& camera_to_world,
                         const CameraIntrinsics& k, float baseline, std::vector<float>* depth) {
  Eigen::Isometry3f projector_to_world = camera_to_world;
  projector_to_world.translation() += camera_to_world.linear() * Eigen::Vector3f(baseline, 0, 0);
  std::vector<float> lit(depth->size(), std::numeric_limits<float>::infinity());
  Rasterizer rasterizer(k, &lit, nullptr);
  const Eigen::Isometry3f world_to_projector = projector_to_world.inverse();
  std::vector<Eigen::Vector3f> vertices;
  for (const Mesh* mesh : meshes) {
    vertices.resize(mesh->vertices.size());
    for (size_t i = 0; i < mesh->vertices.size(); ++i) vertices[i] = world_to_projector * mesh->vertices[i];
    for (const auto& t : mesh->triangles) rasterizer.drawClipped(vertices[t[0]], vertices[t[1]], vertices[t[2]], 0);
  }
  for (int row = 0; row < k.height; ++row) {
    for (int col = 0; col < k.width; ++col) {
      float& z = (*depth)[static_cast<size_t>(row * k.width + col)];
      if (!std::isfinite(z)) continue;
      // The same point from the projector: shifted by the baseline along x.
      const Eigen::Vector3f p((static_cast<float>(col) - k.cx) * z / k.fx - baseline, (static_cast<float>(row) - k.cy) * z / k.fy, z);
      const long u = std::lround(k.fx * p.x() / p.z() + k.cx), v = std::lround(k.fy * p.y() / p.z() + k.cy);
      if (u < 0 || v < 0 || u >= k.width || v >= k.height) continue;  // outside the pattern's field: left lit
      // A little slack for the pixel grid on slanted surfaces: 2 cm and 3 % of the depth.
      if (lit[static_cast<size_t>(v * k.width + u)] < z - 0.02f - 0.03f * z) z = std::numeric_limits<float>::infinity();
    }
  }
}

DepthImage render(const std::vector<const Mesh*>& meshes, const Eigen::Isometry3f& camera_to_world,
                  const CameraIntrinsics& intrinsics, const NoiseParams& noise, std::vector<int>* label) {
  checkIntrinsics(intrinsics);
  DepthImage image;
  image.intrinsics = intrinsics;
  image.camera_to_world = camera_to_world;
  const size_t pixels = static_cast<size_t>(intrinsics.width) * intrinsics.height;
  image.depth.assign(pixels, std::numeric_limits<float>::infinity());
  if (label != nullptr) label->assign(pixels, -1);
  Rasterizer rasterizer(intrinsics, &image.depth, label);
  const Eigen::Isometry3f world_to_camera = camera_to_world.inverse();
  std::vector<Eigen::Vector3f> camera_vertices;
  for (size_t m = 0; m < meshes.size(); ++m) {
    const Mesh& mesh = *meshes[m];
    camera_vertices.resize(mesh.vertices.size());
    for (size_t i = 0; i < mesh.vertices.size(); ++i) camera_vertices[i] = world_to_camera * mesh.vertices[i];
    for (const auto& t : mesh.triangles) {
      if (t.minCoeff() < 0 || t.maxCoeff() >= static_cast<int>(mesh.vertices.size())) {
        throw Error(ErrorCode::kInvalidInput, "renderDepth: mesh " + std::to_string(m) + " has a triangle index outside its " +
                                                  std::to_string(mesh.vertices.size()) + " vertices");
      }
      rasterizer.drawClipped(camera_vertices[t[0]], camera_vertices[t[1]], camera_vertices[t[2]], static_cast<int>(m));
    }
  }
  if (noise.enabled && noise.projector_shadow && noise.baseline > 0) {
    castProjectorShadow(meshes, camera_to_world, intrinsics, noise.baseline, &image.depth);
  }
  if (noise.enabled) applyCorrelationWindow(&image.depth, label, intrinsics, noise);
  applySensorModel(&image.depth, intrinsics, noise);
  return image;
}

}  // namespace

Mesh floorMesh(float size) {
  const float h = size / 2;
  Mesh floor;
  floor.vertices = {{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}};
  floor.triangles = {{0, 1, 2}, {0, 2, 3}};
  return floor;
}

Eigen::Isometry3f lookAt(const Eigen::Vector3f& eye, const Eigen::Vector3f& target) {
  Eigen::Vector3f forward = target - eye;
  if (!(forward.norm() > 1e-6f)) throw Error(ErrorCode::kInvalidInput, "lookAt: camera eye and target coincide (or are NaN)");
  forward.normalize();
  Eigen::Vector3f right = forward.cross(Eigen::Vector3f::UnitZ());
  if (right.norm() < 1e-4f) {
    throw Error(ErrorCode::kInvalidInput, "lookAt: the camera looks straight up or down, so the image's up is undefined");
  }
  right.normalize();
  Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
  pose.linear().col(0) = right;
  pose.linear().col(1) = forward.cross(right);  // image y points down
  pose.linear().col(2) = forward;
  pose.translation() = eye;
  return pose;
}

std::vector<Eigen::Isometry3f> viewRing(const Mesh& placed_mesh, const ViewRingParams& params,
                                        const CameraIntrinsics& intrinsics) {
  checkIntrinsics(intrinsics);
  if (params.views <= 0) throw Error(ErrorCode::kInvalidInput, "viewRing: views must be > 0, got " + std::to_string(params.views));
  if (placed_mesh.vertices.empty()) throw Error(ErrorCode::kInvalidInput, "viewRing: the mesh has no vertices");
  const Eigen::AlignedBox3f box = placed_mesh.bounds();
  const Eigen::Vector3f center = box.center();
  float distance = params.distance;
  if (distance <= 0) {
    // The bounding sphere fits the narrower half field of view with a 10% margin, so every
    // view sees the whole object whatever its orientation.
    const float half_width = std::min(intrinsics.cx + 0.5f, intrinsics.width - 0.5f - intrinsics.cx);
    const float half_height = std::min(intrinsics.cy + 0.5f, intrinsics.height - 0.5f - intrinsics.cy);
    const float half_fov = std::min(std::atan(half_width / intrinsics.fx), std::atan(half_height / intrinsics.fy));
    distance = std::max(params.min_distance, 1.1f * (box.sizes().norm() / 2) / std::sin(half_fov));
  }
  const float elevation = params.elevation_deg * static_cast<float>(M_PI) / 180.0f;
  std::vector<Eigen::Isometry3f> poses;
  for (int i = 0; i < params.views; ++i) {
    // Counter-clockwise seen from above, starting at the front.
    const float azimuth = -static_cast<float>(M_PI) / 2 + 2 * static_cast<float>(M_PI) * i / params.views;
    const Eigen::Vector3f direction(std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth),
                                    std::sin(elevation));
    poses.push_back(lookAt(center + distance * direction, center));
  }
  return poses;
}

DepthImage renderDepth(const std::vector<const Mesh*>& meshes, const Eigen::Isometry3f& camera_to_world,
                       const CameraIntrinsics& intrinsics, const NoiseParams& noise) {
  return render(meshes, camera_to_world, intrinsics, noise, nullptr);
}

Scene depthImageToWorldScene(const DepthImage& image, const std::string& source) {
  const CameraIntrinsics& k = image.intrinsics;
  checkIntrinsics(k);
  if (image.depth.size() != static_cast<size_t>(k.width) * k.height) {
    throw Error(ErrorCode::kInvalidInput, source + ": depth has " + std::to_string(image.depth.size()) + " values for a " +
                                              std::to_string(k.width) + "x" + std::to_string(k.height) + " image");
  }
  Scene scene;
  scene.source = source;
  scene.image_width = k.width;
  scene.image_height = k.height;
  scene.sensor_origin = image.camera_to_world.translation();
  scene.sensor_orientation = Eigen::Quaternionf(image.camera_to_world.linear());
  for (int row = 0; row < k.height; ++row) {
    for (int col = 0; col < k.width; ++col) {
      const int index = row * k.width + col;
      const float z = image.depth[index];
      if (!(z > 0) || !std::isfinite(z)) continue;
      const Eigen::Vector3f camera_point((col - k.cx) * z / k.fx, (row - k.cy) * z / k.fy, z);
      PointT point;
      point.getVector3fMap() = image.camera_to_world * camera_point;
      scene.cloud->push_back(point);
      scene.pixel_index.push_back(index);
    }
  }
  scene.cloud->sensor_origin_ << scene.sensor_origin, 0.0f;
  scene.cloud->sensor_orientation_ = scene.sensor_orientation;
  return scene;
}

Scene fusedCloud(const std::vector<Eigen::Vector3f>& points, float spacing, const Eigen::Vector3f& viewpoint,
                 const std::string& source) {
  if (!(spacing > 0)) throw Error(ErrorCode::kInvalidInput, source + ": fusion spacing must be > 0");
  std::unordered_map<uint64_t, std::pair<Eigen::Vector3f, int>> cells;
  const auto cell = [&](float x) {
    return static_cast<uint64_t>(static_cast<int64_t>(std::floor(x / spacing)) + (1 << 20));
  };
  for (const auto& p : points) {
    auto& c = cells.try_emplace((cell(p.x()) << 42) | (cell(p.y()) << 21) | cell(p.z()), Eigen::Vector3f::Zero(), 0)
                  .first->second;
    c.first += p;
    ++c.second;
  }
  Scene scene;
  scene.source = source;
  scene.sensor_origin = viewpoint;
  scene.up = Eigen::Vector3f::UnitZ();
  for (const auto& [key, c] : cells) {
    PointT point;
    point.getVector3fMap() = c.first / static_cast<float>(c.second);
    scene.cloud->push_back(point);
  }
  scene.cloud->sensor_origin_ << viewpoint, 0.0f;
  return scene;
}

void saveDepthPng(const DepthImage& image, float units_per_metre, const std::string& path) {
  if (!(units_per_metre > 0)) {
    throw Error(ErrorCode::kInvalidInput, path + ": depth units per metre must be > 0, got " + std::to_string(units_per_metre));
  }
  DepthPng png;
  png.width = image.intrinsics.width;
  png.height = image.intrinsics.height;
  png.pixels.reserve(image.depth.size());
  for (float z : image.depth) {
    const float units = std::round(z * units_per_metre);
    if (!(units >= 0 && units <= 65535)) {
      throw Error(ErrorCode::kInvalidInput, path + ": depth " + std::to_string(z) + " m does not fit 16 bits at " +
                                                std::to_string(units_per_metre) + " units per metre");
    }
    png.pixels.push_back(static_cast<uint16_t>(units));
  }
  writeFileBytes(path, encodeDepthPng16(png));
}

SyntheticScene composeScene(const std::vector<SceneObject>& objects, const SyntheticSceneParams& params) {
  SyntheticScene result;
  std::vector<Mesh> world_meshes;
  world_meshes.reserve(objects.size() + 1);
  for (const SceneObject& object : objects) {
    if (object.mesh.triangles.empty()) {
      throw Error(ErrorCode::kInvalidInput, "composeScene: the mesh of object '" + object.category + "' has no triangles");
    }
    const Eigen::Isometry3f pose(Eigen::Translation3f(object.x, object.y, 0) *
                                 Eigen::AngleAxisf(object.yaw, Eigen::Vector3f::UnitZ()));
    world_meshes.push_back(transformed(object.mesh, pose));
    const Eigen::AlignedBox3f box = object.mesh.bounds();
    GroundTruthObject truth;
    truth.category = object.category;
    truth.center = pose * box.center();
    truth.size = box.sizes();
    truth.yaw = object.yaw;
    result.objects.push_back(truth);
  }
  if (params.floor_size > 0) world_meshes.push_back(floorMesh(params.floor_size));
  std::vector<const Mesh*> meshes;
  for (const Mesh& mesh : world_meshes) meshes.push_back(&mesh);

  std::vector<int> label;
  result.depth = render(meshes, lookAt(params.camera_eye, params.camera_target), params.intrinsics, params.noise, &label);
  result.scene = depthImageToWorldScene(result.depth, "synthetic scene");
  result.point_object.reserve(result.scene.pixel_index.size());
  for (int pixel : result.scene.pixel_index) {
    const int id = label[pixel];
    const bool on_object = id >= 0 && id < static_cast<int>(objects.size());
    result.point_object.push_back(on_object ? id : -1);
    if (on_object) ++result.objects[id].points;
  }
  return result;
}

}  // namespace ism
