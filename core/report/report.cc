#include "core/report/report.h"

#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

#include "core/common/error.h"
#include "core/gravity/viewpoint.h"
#include "core/io/cloud_io.h"
#include "core/io/file_bytes.h"

namespace ism {
namespace {

nlohmann::json toJson(const Eigen::Vector3f& v) { return {v.x(), v.y(), v.z()}; }

// One RGB image with a depth buffer, so that nearer points win and boxes are drawn on top.
struct Canvas {
  int width, height;
  std::vector<uint8_t> rgb;
  std::vector<float> depth;
  Canvas(int w, int h) : width(w), height(h), rgb(static_cast<size_t>(w) * h * 3, 0), depth(static_cast<size_t>(w) * h, INFINITY) {}

  void set(int u, int v, const Eigen::Vector3i& color) {
    if (u < 0 || v < 0 || u >= width || v >= height) return;
    uint8_t* p = &rgb[(static_cast<size_t>(v) * width + u) * 3];
    for (int c = 0; c < 3; ++c) p[c] = static_cast<uint8_t>(std::clamp(color[c], 0, 255));
  }

  void splat(int u, int v, float z, const Eigen::Vector3i& color, int size) {
    for (int dv = 0; dv < size; ++dv) {
      for (int du = 0; du < size; ++du) {
        const int x = u + du, y = v + dv;
        if (x < 0 || y < 0 || x >= width || y >= height) continue;
        float& d = depth[static_cast<size_t>(y) * width + x];
        if (z < d) {
          d = z;
          set(x, y, color);
        }
      }
    }
  }

  void line(Eigen::Vector2f a, Eigen::Vector2f b, const Eigen::Vector3i& color, int thickness) {
    const int steps = static_cast<int>(std::ceil((b - a).cwiseAbs().maxCoeff())) + 1;
    if (steps > 4 * (width + height)) return;  // degenerate projection of a far-off edge
    for (int i = 0; i <= steps; ++i) {
      const Eigen::Vector2f p = a + (b - a) * (static_cast<float>(i) / static_cast<float>(steps));
      for (int dv = 0; dv < thickness; ++dv) {
        for (int du = 0; du < thickness; ++du) {
          set(static_cast<int>(std::lround(p.x())) + du - thickness / 2, static_cast<int>(std::lround(p.y())) + dv - thickness / 2, color);
        }
      }
    }
  }
};

}  // namespace

std::string hypothesesTable(const RecognitionResult& result, bool include_rejected) {
  std::string out;
  char line[256];
  std::snprintf(line, sizeof line, "%-16s %10s %8s %9s %24s %18s %7s %5s%s\n", "category", "confidence", "score",
                "threshold", "centre (m)", "box (m)", "support", "fit", include_rejected ? "  selection" : "");
  out += line;
  const auto add = [&](const Hypothesis& h, const char* selection) {
    char fit[16] = "    -";  // not verified
    if (h.verification) std::snprintf(fit, sizeof fit, "%5.2f", h.verification->fit());
    std::snprintf(line, sizeof line, "%-16s %10.3f %8.3f %9.3f %7.2f %7.2f %7.2f   %5.2f %5.2f %5.2f %7d %s%s%s\n",
                  h.category.c_str(), h.confidence, h.score, h.threshold, h.center.x(), h.center.y(), h.center.z(),
                  h.box.size.x(), h.box.size.y(), h.box.size.z(), h.support, fit, include_rejected ? "  " : "",
                  selection);
    out += line;
    for (const auto& a : h.alternatives) {
      std::snprintf(line, sizeof line, "  or %-12s %10.3f\n", a.category.c_str(), a.confidence);
      out += line;
    }
  };
  for (const auto& h : result.hypotheses) add(h, include_rejected ? (h.passed_selection ? "passed" : "failed") : "");
  if (include_rejected) {
    for (const auto& h : result.rejected) add(h, "rejected");
  }
  if (result.hypotheses.empty() && (!include_rejected || result.rejected.empty())) out += "(no hypotheses)\n";
  return out;
}

nlohmann::json toJson(const Hypothesis& h) {
  nlohmann::json alternatives = nlohmann::json::array();
  for (const auto& a : h.alternatives) alternatives.push_back({{"category", a.category}, {"confidence", a.confidence}});
  nlohmann::json j = {{"category", h.category},
                      {"confidence", h.confidence},
                      {"alternatives", alternatives},
                      {"score", h.score},
                      {"threshold", h.threshold},
                      {"center", toJson(h.center)},
                      {"box",
                       {{"center", toJson(h.box.center)},
                        {"size", toJson(h.box.size)},
                        {"rotation_wxyz", {h.box.rotation.w(), h.box.rotation.x(), h.box.rotation.y(), h.box.rotation.z()}}}},
                      {"support", h.support},
                      {"support_centroid", toJson(h.support_centroid)},
                      {"upright_box", h.upright_box},
                      {"passed_selection", h.passed_selection}};
  if (h.verification) {
    const Verification& v = *h.verification;
    j["verification"] = {{"fit", v.fit()},          {"seen", v.seen},     {"consistent", v.consistent}, {"claimed", v.claimed}, {"profile_distance", v.profile_distance},
                         {"training_object", v.object}, {"yaw", v.yaw}, {"center", toJson(v.center)}};
  }
  if (!h.support_keypoints.empty()) {
    auto& points = j["support_keypoints"] = nlohmann::json::array();
    for (const auto& p : h.support_keypoints) points.push_back(toJson(p));
  }
  return j;
}

nlohmann::json toJson(const RecognitionResult& result) {
  nlohmann::json j = {{"hypotheses", nlohmann::json::array()},
                      {"rejected", nlohmann::json::array()},
                      {"timings_ms", nlohmann::json::array()},
                      {"input_points", result.input_points},
                      {"surface_points", result.surface_points},
                      {"keypoints", result.keypoints},
                      {"verified", result.verified}};
  for (const auto& h : result.hypotheses) j["hypotheses"].push_back(toJson(h));
  for (const auto& h : result.rejected) j["rejected"].push_back(toJson(h));
  for (const auto& [stage, ms] : result.timings.stages) j["timings_ms"].push_back({{"stage", stage}, {"ms", ms}});
  if (result.gravity) {
    const Gravity& g = *result.gravity;
    j["gravity"] = {{"up", toJson(g.up)}, {"source", toString(g.source)}, {"floor_points", g.floor_points},
                    {"walls", g.walls}};
    if (g.hasFloor()) j["gravity"]["floor_level"] = *g.floor_level;
  }
  return j;
}

Eigen::Vector3i categoryColor(const std::string& category) {
  // Saturated, mutually distinct hues; the name picks one (FNV-1a, stable across platforms).
  static const Eigen::Vector3i palette[] = {{230, 25, 75},  {60, 180, 75},  {255, 225, 25}, {0, 130, 200},
                                            {245, 130, 48}, {145, 30, 180}, {70, 240, 240}, {240, 50, 230},
                                            {210, 245, 60}, {250, 190, 190}};
  uint32_t hash = 2166136261u;
  for (unsigned char c : category) hash = (hash ^ c) * 16777619u;
  return palette[hash % (sizeof palette / sizeof palette[0])];
}

namespace {

// World-to-camera rotation of the picture of a cloud without an image grid: optical z along the
// points' mean direction from the sensor origin, y down against `up` (else against the sensor
// orientation's up, its -y).
Eigen::Matrix3f cloudViewRotation(const Scene& scene, const std::optional<Eigen::Vector3f>& up_hint) {
  const Eigen::Matrix3f sensor = scene.sensor_orientation.normalized().toRotationMatrix();
  Eigen::Vector3f mean = Eigen::Vector3f::Zero();
  for (const auto& p : scene.cloud->points) {
    const Eigen::Vector3f d = p.getVector3fMap() - scene.sensor_origin;
    if (d.norm() > 1e-6f) mean += d.normalized();
  }
  Eigen::Vector3f forward = mean.norm() > 1e-3f * scene.cloud->size() ? mean.normalized() : sensor.col(2);
  Eigen::Vector3f up = up_hint && up_hint->norm() > 0 ? up_hint->normalized() : Eigen::Vector3f(-sensor.col(1));
  Eigen::Vector3f down = -(up - up.dot(forward) * forward);
  if (down.norm() < 1e-3f) down = forward.unitOrthogonal();  // looking straight up or down
  down.normalize();
  Eigen::Matrix3f camera_to_world;
  camera_to_world.col(0) = down.cross(forward);
  camera_to_world.col(1) = down;
  camera_to_world.col(2) = forward;
  return camera_to_world.transpose();
}

// params' lens, its focal length shrunk (never grown) until the 1st to 99th percentiles of the
// points' image coordinates fit in the picture.
PinholeIntrinsics fittedLens(const Scene& scene, const Eigen::Matrix3f& world_to_camera, const PictureParams& params) {
  std::vector<float> xs, ys;
  for (const auto& p : scene.cloud->points) {
    const Eigen::Vector3f c = world_to_camera * (p.getVector3fMap() - scene.sensor_origin);
    if (!(c.z() > 0.05f)) continue;
    xs.push_back(c.x() / c.z());
    ys.push_back(c.y() / c.z());
  }
  PinholeIntrinsics lens = params;
  if (xs.size() < 10) return lens;
  const auto halfExtent = [](std::vector<float>& v) {
    const size_t lo = v.size() / 100, hi = v.size() - 1 - v.size() / 100;
    std::nth_element(v.begin(), v.begin() + lo, v.end());
    const float low = v[lo];
    std::nth_element(v.begin(), v.begin() + hi, v.end());
    return std::max(std::abs(low), std::abs(v[hi]));
  };
  const float fx = 0.5f * params.width / std::max(halfExtent(xs), 1e-3f);
  const float fy = 0.5f * params.height / std::max(halfExtent(ys), 1e-3f);
  const float f = std::min({fx, fy, static_cast<float>(params.fx)});
  lens.fx = lens.fy = f;
  lens.cx = 0.5f * params.width;
  lens.cy = 0.5f * params.height;
  return lens;
}

// A map seen from nowhere (viewpoint.h) shown from outside it: from above one side, looking down
// at its middle, where a sensor in its middle would see only what surrounds it.
std::optional<Eigen::Vector3f> overviewEye(const Scene& scene, const std::optional<Eigen::Vector3f>& up_hint) {
  Scene levelled = scene;  // shares the points
  if (up_hint && up_hint->norm() > 0) levelled.up = up_hint->normalized();
  const std::optional<MapView> view = mapViewpoint(levelled);
  if (!view) return std::nullopt;
  const Eigen::Vector3f& up = view->up;
  const Eigen::Vector3f& middle = view->origin;
  double squared = 0;
  for (const auto& p : scene.cloud->points) {
    const Eigen::Vector3f d = p.getVector3fMap() - middle;
    squared += (d - up * up.dot(d)).squaredNorm();
  }
  const float radius = static_cast<float>(std::sqrt(squared / static_cast<double>(scene.cloud->size())));
  const Eigen::Vector3f side = up.unitOrthogonal();
  return middle + up * (1.2f * radius) - side * (1.5f * radius);
}

}  // namespace

std::string renderPicture(const Scene& given, const std::vector<Hypothesis>& hypotheses, const PictureParams& params,
                          const Model* model) {
  if (params.width <= 0 || params.height <= 0 || params.width > 16384 || params.height > 16384) {
    throw Error(ErrorCode::kInvalidInput, "picture size " + std::to_string(params.width) + "x" +
                                              std::to_string(params.height) + " is out of range");
  }
  Scene scene = given;  // shares the points
  if (scene.image_width == 0) {
    if (const auto eye = overviewEye(scene, params.up)) scene.sensor_origin = *eye;
  }
  Canvas canvas(params.width, params.height);
  // An image whose pose turns its sensor away from its points is drawn in the points' own frame,
  // as recognition takes it (viewpoint.h, facesItsPoints); else the picture would be empty.
  if (scene.image_width > 0 && !facesItsPoints(scene)) scene.sensor_orientation = Eigen::Quaternionf::Identity();
  const Eigen::Matrix3f world_to_camera =
      scene.image_width > 0 ? Eigen::Matrix3f(scene.sensor_orientation.normalized().toRotationMatrix().transpose())
                            : cloudViewRotation(scene, params.up);
  const auto toCamera = [&](const Eigen::Vector3f& p) { return Eigen::Vector3f(world_to_camera * (p - scene.sensor_origin)); };
  PinholeIntrinsics lens = params;
  if (scene.image_width == 0) lens = fittedLens(scene, world_to_camera, params);
  const auto project = [&](const Eigen::Vector3f& c) {
    return Eigen::Vector2f(lens.fx * c.x() / c.z() + lens.cx, lens.fy * c.y() / c.z() + lens.cy);
  };

  std::vector<Eigen::Vector3f> camera_points;
  camera_points.reserve(scene.cloud->size());
  float near = INFINITY, far = 0;
  for (const auto& p : scene.cloud->points) {
    camera_points.push_back(toCamera(p.getVector3fMap()));
    if (camera_points.back().z() > 0) {
      near = std::min(near, camera_points.back().z());
      far = std::max(far, camera_points.back().z());
    }
  }
  // An image-like scene fills the frame at one pixel per point; an unorganised cloud gets dots as
  // large as the picture's area shared among its points (2-6 px), so a sparse sample still shows
  // surfaces.
  int dot = 1;
  if (scene.image_width == 0) {
    const double pixels_per_point = static_cast<double>(params.width) * params.height / std::max<size_t>(camera_points.size(), 1);
    dot = std::clamp(static_cast<int>(std::lround(std::sqrt(pixels_per_point))), 2, 6);
  }
  for (size_t i = 0; i < camera_points.size(); ++i) {
    const Eigen::Vector3f& c = camera_points[i];
    if (!(c.z() > 0)) continue;
    const Eigen::Vector2f uv = project(c);
    Eigen::Vector3i color;
    if (scene.has_color) {
      const auto& p = scene.cloud->points[i];
      color = Eigen::Vector3i(p.r, p.g, p.b);
    } else {
      const float t = far > near ? (c.z() - near) / (far - near) : 0.0f;
      color = Eigen::Vector3i::Constant(static_cast<int>(230 - 170 * t));
    }
    canvas.splat(static_cast<int>(std::floor(uv.x())), static_cast<int>(std::floor(uv.y())), c.z(), color, dot);
  }

  constexpr float kNearPlane = 0.05f;  // edges are clipped here so that nothing behind the sensor projects
  for (const auto& h : hypotheses) {
    if (model == nullptr || !h.verification) continue;
    // By name here (Model::find is in the model library, which reports do not link).
    const auto category = std::find_if(model->categories.begin(), model->categories.end(),
                                       [&](const CategoryModel& c) { return c.name == h.category; });
    if (category == model->categories.end() || h.verification->object < 0 ||
        h.verification->object >= static_cast<int>(category->objects.size())) {
      continue;
    }
    // The shape stands on its box's bottom (TrainingObject: centred on x = y = 0, on z = 0), turned
    // as the fitted box is; 3 cm of depth bias lets it show on the surface it agrees with.
    const TrainingObject& shape = category->objects[static_cast<size_t>(h.verification->object)];
    const Eigen::Matrix3f axes = h.box.rotation.toRotationMatrix();
    const Eigen::Vector3f bottom(0, 0, shape.size.z() / 2);
    const Eigen::Vector3i color = categoryColor(h.category);
    for (const auto& q : shape.surface) {
      const Eigen::Vector3f c = toCamera(h.box.center + axes * (q - bottom));
      if (!(c.z() > kNearPlane)) continue;
      const Eigen::Vector2f uv = project(c);
      canvas.splat(static_cast<int>(std::floor(uv.x())), static_cast<int>(std::floor(uv.y())), c.z() - 0.03f, color,
                   std::max(2, dot));
    }
  }
  for (const auto& h : hypotheses) {
    const Eigen::Matrix3f axes = h.box.rotation.toRotationMatrix();
    Eigen::Vector3f corners[8];
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3f sign((i & 1) ? 0.5f : -0.5f, (i & 2) ? 0.5f : -0.5f, (i & 4) ? 0.5f : -0.5f);
      corners[i] = toCamera(h.box.center + axes * sign.cwiseProduct(h.box.size));
    }
    const Eigen::Vector3i color = categoryColor(h.category);
    for (int a = 0; a < 8; ++a) {
      for (int bit : {1, 2, 4}) {
        if (a & bit) continue;
        Eigen::Vector3f p = corners[a], q = corners[a | bit];
        if (p.z() < kNearPlane && q.z() < kNearPlane) continue;
        if (p.z() < kNearPlane) std::swap(p, q);
        if (q.z() < kNearPlane) q = p + (q - p) * ((p.z() - kNearPlane) / (p.z() - q.z()));
        canvas.line(project(p), project(q), color, params.line_width);
      }
    }
  }

  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(params.width);
  image.height = static_cast<png_uint_32>(params.height);
  image.format = PNG_FORMAT_RGB;
  png_alloc_size_t size = 0;
  if (!png_image_write_to_memory(&image, nullptr, &size, 0, canvas.rgb.data(), 0, nullptr)) {
    throw Error(ErrorCode::kInternal, std::string("PNG encoding failed: ") + image.message);
  }
  std::string bytes(size, '\0');
  if (!png_image_write_to_memory(&image, bytes.data(), &size, 0, canvas.rgb.data(), 0, nullptr)) {
    throw Error(ErrorCode::kInternal, std::string("PNG encoding failed: ") + image.message);
  }
  bytes.resize(size);
  return bytes;
}

void savePicture(const Scene& scene, const std::vector<Hypothesis>& hypotheses, const std::string& path,
                 const PictureParams& params, const Model* model) {
  writeFileBytes(path, renderPicture(scene, hypotheses, params, model));
}

void saveDebugPly(const Model& model, const RecognitionResult& result, const std::string& path) {
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3i> colors;
  for (const auto& p : result.keypoint_positions) {
    points.push_back(p);
    colors.emplace_back(255, 255, 255);
  }
  float heaviest = 0;
  for (const auto& v : result.votes) heaviest = std::max(heaviest, v.weight);
  for (const auto& v : result.votes) {
    points.push_back(v.position);
    const float brightness = heaviest > 0 ? 0.3f + 0.7f * v.weight / heaviest : 1.0f;
    const Eigen::Vector3i base = categoryColor(model.categories.at(static_cast<size_t>(v.category)).name);
    colors.push_back((base.cast<float>() * brightness).cast<int>());
  }
  for (const auto& h : result.hypotheses) {
    points.push_back(h.center);
    colors.emplace_back(255, 0, 0);
  }
  savePlyPoints(points, colors, path);
}

}  // namespace ism
