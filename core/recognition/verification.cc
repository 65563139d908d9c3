#include "core/recognition/verification.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>

#include <Eigen/Geometry>

#include "core/common/upright_box.h"
#include "core/frontend/neighbour_grid.h"
#include "core/gravity/viewpoint.h"

namespace ism {
namespace {

constexpr float kPi = static_cast<float>(M_PI);

// A pinhole view from the sensor towards the hypothesis, in the gravity frame relative to the
// sensor: pixel coordinates are tangents (u = x / z, v = y / z) in units of `pixel`.
struct LocalView {
  Eigen::Matrix3f axes;  // rows: the view's x, y and z (towards the hypothesis)
  float half = 0;        // half the window's width, in tangent units
  float pixel = 0;
  int width = 0;
  std::vector<float> depth;  // the nearest measured depth per pixel; infinity where none

  // The pixel of q, a point in the view's axes (axes * p for p relative to the sensor), and its
  // depth, or -1 outside the window.
  int project(const Eigen::Vector3f& q, float& z) const {
    z = q.z();
    if (!(z > 0.05f)) return -1;
    const float inverse = 1.0f / z;
    const float u = q.x() * inverse + half, v = q.y() * inverse + half;
    if (!(u >= 0 && v >= 0)) return -1;
    const int col = static_cast<int>(u / pixel), row = static_cast<int>(v / pixel);
    if (col >= width || row >= width) return -1;
    return row * width + col;
  }
};

// The measured depths around `center` (relative to the sensor) within `radius`; nothing when the
// sensor is inside that sphere or sees too few points there. The pixel follows the scene's own
// density in the window (the points spread over its solid angle), so a sparse room sample and a
// dense depth frame both fill about two thirds of their pixels.
std::optional<LocalView> lookAt(const VerificationScene& scene, const Eigen::Vector3f& center, float radius) {
  const float distance = center.norm();
  if (!(distance > 1.1f * radius)) return std::nullopt;
  LocalView view;
  const Eigen::Vector3f forward = center / distance;
  Eigen::Vector3f side = Eigen::Vector3f::UnitZ().cross(forward);
  if (side.norm() < 1e-3f) side = Eigen::Vector3f::UnitX().cross(forward);
  side.normalize();
  view.axes.row(0) = side.transpose();
  view.axes.row(1) = forward.cross(side).transpose();
  view.axes.row(2) = forward.transpose();
  view.half = radius / std::sqrt(distance * distance - radius * radius);
  std::vector<std::pair<float, float>> inside;  // (u, v) + half, then binned
  std::vector<float> depths;
  inside.reserve(scene.points.size());
  depths.reserve(scene.points.size());
  for (const auto& p : scene.points) {
    const Eigen::Vector3f q = view.axes * p;
    if (!(q.z() > 0.05f)) continue;
    const float u = q.x() / q.z(), v = q.y() / q.z();
    if (std::abs(u) >= view.half || std::abs(v) >= view.half) continue;
    inside.emplace_back(u + view.half, v + view.half);
    depths.push_back(q.z());
  }
  constexpr size_t kMinPoints = 30;
  if (inside.size() < kMinPoints) return std::nullopt;
  const float spacing = 2 * view.half / std::sqrt(static_cast<float>(inside.size()));
  view.pixel = std::clamp(1.5f * spacing, 0.002f, 0.05f);
  view.width = std::max(1, static_cast<int>(std::ceil(2 * view.half / view.pixel)));
  view.depth.assign(static_cast<size_t>(view.width) * static_cast<size_t>(view.width),
                    std::numeric_limits<float>::infinity());
  for (size_t i = 0; i < inside.size(); ++i) {
    const int col = std::min(view.width - 1, static_cast<int>(inside[i].first / view.pixel));
    const int row = std::min(view.width - 1, static_cast<int>(inside[i].second / view.pixel));
    float& d = view.depth[static_cast<size_t>(row * view.width + col)];
    d = std::min(d, depths[i]);
  }
  return view;
}

float depthMargin(float z, float margin) {
  const float sigma = 0.0012f + 0.0019f * (z - 0.4f) * (z - 0.4f);
  return margin + 2 * sigma;
}

struct Pose {
  int object = 0;
  float yaw = 0;
  Eigen::Vector2f xy = Eigen::Vector2f::Zero();  // box centre, relative to the sensor
};

struct Agreement {
  int seen = 0, consistent = 0, tested = 0;
  int hidden = 0;   // behind nearer measured surface
  int claimed = 0;  // agreeing, on surface a better hypothesis explained
  // What poses are ranked by: agreeing minus twice the seen-through share of the points looked
  // at, so that a larger shape does not win by its size alone.
  float rank() const { return tested > 0 ? static_cast<float>(consistent - 2 * (seen - consistent)) / static_cast<float>(tested) : 0.0f; }

  // The counts as `terms` weigh them (FitTerms): seen becomes the pixels the fit is a share of,
  // consistent those counted for it.
  Agreement weighed(FitTerms terms) const {
    Agreement a = *this;
    if (terms == FitTerms::kInliers) {
      a.seen = seen + hidden;
    } else if (terms == FitTerms::kFreeSpace) {
      a.seen = seen + hidden;
      a.consistent = consistent + hidden;
    }
    return a;
  }
};

// The cubes better hypotheses explained, copied once per verified hypothesis into an open-addressing
// table: the agreement of every pose looks each agreeing point's cube up in it.
class CellSet {
 public:
  explicit CellSet(const std::unordered_set<uint64_t>* cells) {
    if (cells == nullptr || cells->empty()) return;
    size_t size = 16;
    while (size < 2 * cells->size()) size *= 2;
    mask_ = size - 1;
    slots_.assign(size, kEmpty);
    for (const uint64_t c : *cells) {
      size_t i = slot(c);
      while (slots_[i] != kEmpty) i = (i + 1) & mask_;
      slots_[i] = c;
    }
  }
  bool empty() const { return slots_.empty(); }
  bool contains(uint64_t c) const {
    if (slots_.empty()) return false;
    for (size_t i = slot(c);; i = (i + 1) & mask_) {
      if (slots_[i] == c) return true;
      if (slots_[i] == kEmpty) return false;
    }
  }

 private:
  static constexpr uint64_t kEmpty = ~uint64_t{0};  // cellOf packs 63 bits, never all ones
  size_t slot(uint64_t c) const { return static_cast<size_t>((c * 0x9E3779B97F4A7C15ull) >> 32) & mask_; }
  std::vector<uint64_t> slots_;
  size_t mask_ = 0;
};

// A cube of the gravity frame, for the surface a hypothesis has explained.
uint64_t cellOf(const Eigen::Vector3f& p, float edge) {
  const Eigen::Vector3i c = (p / edge).array().floor().cast<int>();
  return (static_cast<uint64_t>(static_cast<uint32_t>(c.x()) & 0x1fffff) << 42) |
         (static_cast<uint64_t>(static_cast<uint32_t>(c.y()) & 0x1fffff) << 21) |
         static_cast<uint64_t>(static_cast<uint32_t>(c.z()) & 0x1fffff);
}

// A shape point agrees with a map where a measured point lies in its cube of this edge or a
// neighbouring one (3-9 cm off): the front end's voxel (kDefaultLeafSize), the map's resolution
// as recognition reads it.
constexpr float kNearCell = 0.03f;

// The rotation of a pose's shape about up.
Eigen::Matrix3f headingOf(const Pose& pose) {
  const float c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  Eigen::Matrix3f turn;
  turn << c, -s, 0, s, c, 0, 0, 0, 1;
  return turn;
}

// A map's pose in 3D: each of the shape's first `points` points above the floor agrees when a
// measured point lies within about a cell of it, and is seen either way. No sensor says which
// parts should have been seen, so an unscanned underside counts against every pose alike.
Agreement agreementInMap(const VerificationScene& scene, float floor_z, const CellSet& claimed,
                         const std::vector<Eigen::Vector3f>& shape, int points, const Pose& pose,
                         std::unordered_set<uint64_t>* explained) {
  const Eigen::Matrix3f turn = headingOf(pose);
  const Eigen::Vector3f offset(pose.xy.x(), pose.xy.y(), floor_z);
  const int n = std::min<int>(points, static_cast<int>(shape.size()));
  Agreement a;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f& local = shape[static_cast<size_t>(i)];
    if (local.z() < 0.05f) continue;  // on the floor, which is measured anywhere
    const Eigen::Vector3f p = turn * local + offset;
    ++a.tested;
    ++a.seen;
    if (!scene.near.contains(p)) continue;
    const uint64_t surface = cellOf(p, 0.05f);
    if (claimed.contains(surface)) {
      --a.seen;
      ++a.claimed;
      continue;
    }
    ++a.consistent;
    if (explained != nullptr) explained->insert(surface);
  }
  return a;
}

struct ShapeView {
  const LocalView& view;
  float floor_z = 0;
  float margin = 0;
  const CellSet& claimed;  // explained by a better hypothesis
  float cell = 0.04f;
  FitTerms terms = FitTerms::kBoth;
};

// A z-buffer of the shape's points over a LocalView's pixels, kept between poses: only the
// pixels a pose touched are cleared after it.
struct ShapeBuffer {
  struct Pixel {
    float z = 0;     // the nearest shape point's depth, where index is set
    int index = -1;  // the nearest shape point; -1 where none
  };
  std::vector<Pixel> pixels;
  std::vector<int> touched;
  explicit ShapeBuffer(size_t size) : pixels(size) {}
};

// The shape's first n points turned by `pose`'s heading into the view's axes: what poses that
// differ only in their shift along the floor share.
void turnIntoView(const LocalView& view, const std::vector<Eigen::Vector3f>& shape, int n, const Pose& pose,
                  std::vector<Eigen::Vector3f>& turned) {
  const Eigen::Matrix3f to_view = view.axes * headingOf(pose);
  turned.resize(static_cast<size_t>(std::max(0, n)));
  for (int i = 0; i < n; ++i) turned[static_cast<size_t>(i)] = to_view * shape[static_cast<size_t>(i)];
}

// The front-most of the shape's first n points at least min_height above the floor, per pixel of
// the view: buffer.touched lists the pixels set. `turned`, when given, holds the points turned
// into the view (turnIntoView) for the pose's heading.
void fillShapeBuffer(const ShapeView& sv, const std::vector<Eigen::Vector3f>& shape, int n, const Pose& pose,
                     float min_height, ShapeBuffer& buffer, const std::vector<Eigen::Vector3f>* turned = nullptr) {
  buffer.touched.clear();
  // The pose and the view in one affine map: the shape's points go straight into the view's axes.
  // Turned points need only the shift, so their heading's turn is not made again per pose.
  const Eigen::Matrix3f to_view = turned == nullptr ? Eigen::Matrix3f(sv.view.axes * headingOf(pose))
                                                    : Eigen::Matrix3f::Identity();
  const Eigen::Vector3f view_offset = sv.view.axes * Eigen::Vector3f(pose.xy.x(), pose.xy.y(), sv.floor_z);
  for (int i = 0; i < n; ++i) {
    if (shape[static_cast<size_t>(i)].z() < min_height) continue;
    float z = 0;
    const Eigen::Vector3f in_view =
        turned != nullptr ? Eigen::Vector3f((*turned)[static_cast<size_t>(i)] + view_offset)
                          : Eigen::Vector3f(to_view * shape[static_cast<size_t>(i)] + view_offset);
    const int pixel = sv.view.project(in_view, z);
    if (pixel < 0) continue;
    ShapeBuffer::Pixel& nearest = buffer.pixels[static_cast<size_t>(pixel)];
    if (nearest.index < 0) {
      buffer.touched.push_back(pixel);
      nearest = {z, i};
    } else if (z < nearest.z) {  // the first of equally near points stays
      nearest = {z, i};
    }
  }
}

// The front-most of the shape's first `points` points per pixel against the measured depth there.
// Measured surface a better hypothesis of the category already explained counts neither way:
// two overlapping hypotheses do not both take credit for one surface. With `explained`, the cells
// of the agreeing points are added to it.
Agreement agreement(const ShapeView& sv, const std::vector<Eigen::Vector3f>& shape, int points, const Pose& pose,
                    ShapeBuffer& buffer, std::unordered_set<uint64_t>* explained = nullptr,
                    const std::vector<Eigen::Vector3f>* turned = nullptr) {
  const int n = std::min<int>(points, static_cast<int>(shape.size()));
  fillShapeBuffer(sv, shape, n, pose, -std::numeric_limits<float>::infinity(), buffer, turned);
  const Eigen::Matrix3f turn = headingOf(pose);
  const Eigen::Vector3f offset(pose.xy.x(), pose.xy.y(), sv.floor_z);
  // The measured surface's cell is wanted only to check or record what a hypothesis explains.
  const bool check_claimed = !sv.claimed.empty();
  const bool cell_needed = check_claimed || explained != nullptr;
  Agreement a;
  a.tested = n;
  for (const int pixel : buffer.touched) {
    ShapeBuffer::Pixel& nearest = buffer.pixels[static_cast<size_t>(pixel)];
    const float z = nearest.z;
    const int index = nearest.index;
    nearest.index = -1;
    const float measured = sv.view.depth[static_cast<size_t>(pixel)];
    const float m = depthMargin(z, sv.margin);
    if (!std::isfinite(measured)) continue;  // no measurement
    if (measured < z - m) {  // something in front
      ++a.hidden;
      continue;
    }
    if (measured > z + m) {  // seen through
      ++a.seen;
      continue;
    }
    // The measured surface point behind the shape's: on the same ray, at the measured depth.
    const uint64_t surface = cell_needed ? cellOf((turn * shape[static_cast<size_t>(index)] + offset) * (measured / z), sv.cell) : 0;
    if (check_claimed && sv.claimed.contains(surface)) {
      ++a.claimed;
      continue;
    }
    ++a.seen;
    ++a.consistent;
    if (explained != nullptr) explained->insert(surface);
  }
  return a;
}

// A pose's agreement: in 3D for a map, else on the depth buffer of sv.view (`turned` as
// fillShapeBuffer's).
Agreement poseAgreement(const VerificationScene& scene, const ShapeView& sv, const std::vector<Eigen::Vector3f>& shape,
                        int points, const Pose& pose, ShapeBuffer& buffer,
                        std::unordered_set<uint64_t>* explained = nullptr,
                        const std::vector<Eigen::Vector3f>* turned = nullptr) {
  return (scene.map ? agreementInMap(scene, sv.floor_z, sv.claimed, shape, points, pose, explained)
                    : agreement(sv, shape, points, pose, buffer, explained, turned))
      .weighed(sv.terms);
}

}  // namespace

NearGrid::NearGrid(const std::vector<Eigen::Vector3f>& points, float cell) {
  if (points.empty()) return;
  Eigen::Vector3f max = points.front();
  min_ = points.front();
  for (const auto& p : points) min_ = min_.cwiseMin(p), max = max.cwiseMax(p);
  min_ -= Eigen::Vector3f::Constant(cell);  // room for the cubes around the outermost points
  max += Eigen::Vector3f::Constant(cell);
  const Eigen::Vector3f extent = max - min_;
  cell_ = std::max(cell, std::cbrt(extent.prod() / static_cast<float>(kMaxCells)));
  dims_ = (extent / cell_).array().floor().cast<int>() + 1;
  bits_.assign((static_cast<size_t>(dims_.x()) * static_cast<size_t>(dims_.y()) * static_cast<size_t>(dims_.z()) + 63) / 64, 0);
  for (const auto& p : points) {
    const Eigen::Vector3i c = ((p - min_) / cell_).array().floor().cast<int>();
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const Eigen::Vector3i n = c + Eigen::Vector3i(dx, dy, dz);
          if ((n.array() < 0).any() || (n.array() >= dims_.array()).any()) continue;
          const size_t i = (static_cast<size_t>(n.z()) * static_cast<size_t>(dims_.y()) + static_cast<size_t>(n.y())) *
                               static_cast<size_t>(dims_.x()) + static_cast<size_t>(n.x());
          bits_[i / 64] |= uint64_t{1} << (i % 64);
        }
      }
    }
  }
}

bool NearGrid::contains(const Eigen::Vector3f& p) const {
  if (bits_.empty()) return false;
  const Eigen::Vector3f f = (p - min_) / cell_;
  if ((f.array() < 0).any()) return false;
  const Eigen::Vector3i c = f.array().floor().cast<int>();
  if ((c.array() >= dims_.array()).any()) return false;
  const size_t i = (static_cast<size_t>(c.z()) * static_cast<size_t>(dims_.y()) + static_cast<size_t>(c.y())) *
                       static_cast<size_t>(dims_.x()) + static_cast<size_t>(c.x());
  return (bits_[i / 64] >> (i % 64)) & 1u;
}

SceneBox sceneBox(const VerificationScene& scene, const Hypothesis& hypothesis) {
  SceneBox local;
  local.box = uprightBoxOf(hypothesis.box, scene.to_gravity);
  local.box.center -= scene.to_gravity * scene.origin;
  local.floor_z = scene.floor_z.value_or(local.box.center.z() - local.box.size.z() / 2);
  local.cos_yaw = std::cos(local.box.yaw);
  local.sin_yaw = std::sin(local.box.yaw);
  return local;
}

int sensorSide(const VerificationScene& scene, const SceneBox& local) {
  if (scene.map) return -1;
  const Eigen::Vector3f sensor = local.boxFrame(Eigen::Vector3f::Zero());  // the points' origin
  const float beyond_x = std::abs(sensor.x()) - local.box.size.x() / 2;
  const float beyond_y = std::abs(sensor.y()) - local.box.size.y() / 2;
  if (beyond_x <= 0 && beyond_y <= 0) return -1;
  return beyond_x > beyond_y ? (sensor.x() > 0 ? 0 : 1) : (sensor.y() > 0 ? 2 : 3);
}

VerificationScene makeVerificationScene(const Scene& scene, const std::optional<Gravity>& gravity,
                                        const VerificationParams& params) {
  VerificationScene out;
  out.origin = scene.sensor_origin;
  if (gravity) {
    out.to_gravity = gravity->toGravity();
    if (gravity->hasFloor()) out.floor_z = *gravity->floor_level - gravity->up.dot(scene.sensor_origin);
  }
  const size_t n = scene.cloud->size();
  const size_t stride = std::max<size_t>(1, (n + params.max_scene_points - 1) / std::max<size_t>(1, params.max_scene_points));
  out.points.reserve(n / stride + 1);
  for (size_t i = 0; i < n; i += stride) {
    out.points.push_back(out.to_gravity * ((*scene.cloud)[i].getVector3fMap() - out.origin));
  }
  if (params.maps_in_3d && isMap(scene)) {
    out.map = true;
    out.near = NearGrid(out.points, kNearCell);
  }
  return out;
}

ShapeProfile shapeProfile(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector3f& size) {
  ShapeProfile profile;
  const Eigen::Vector3f half = (size.array().max(1e-3f) * Eigen::Array3f(0.5f, 0.5f, 1.0f)).matrix();
  for (const auto& p : points) {
    const float ring = std::max(std::abs(p.x()) / half.x(), std::abs(p.y()) / half.y());
    const float height = p.z() / half.z();
    const int r = std::clamp(static_cast<int>(ring * ShapeProfile::kRings), 0, ShapeProfile::kRings - 1);
    const int h = std::clamp(static_cast<int>(height * 10), 0, ShapeProfile::kHeights - 1);
    profile.share[static_cast<size_t>(h * ShapeProfile::kRings + r)] += 1;
    ++profile.points;
  }
  if (profile.points > 0) {
    for (auto& v : profile.share) v /= static_cast<float>(profile.points);
  }
  return profile;
}

float profileDistance(const ShapeProfile& a, const ShapeProfile& b) {
  float sum = 0;
  for (size_t i = 0; i < a.share.size(); ++i) {
    const float total = a.share[i] + b.share[i];
    if (total > 0) sum += (a.share[i] - b.share[i]) * (a.share[i] - b.share[i]) / total;
  }
  return sum;
}

namespace {

// The profiles of the category's training shapes, each in its own box, in the order of its objects.
std::vector<ShapeProfile> trainedProfiles(const CategoryModel& category) {
  std::vector<ShapeProfile> out;
  for (const auto& o : category.objects) {
    if (!o.surface.empty()) out.push_back(shapeProfile(o.surface, o.size));
  }
  return out;
}

// The distance of the measured surface in the fitted box (a tenth wider on each side, from 3 cm
// above its bottom, to skip the floor, up to 15 cm above its top) to the nearest of the
// category's training shapes' profiles (trainedProfiles); 2 with fewer than 10 points to judge by.
float profileDistanceAt(const VerificationScene& scene, const std::vector<ShapeProfile>& trained,
                        const Eigen::Vector3f& bottom, float yaw, const Eigen::Vector3f& size) {
  const float c = std::cos(yaw), s = std::sin(yaw);
  const float hx = 0.55f * size.x(), hy = 0.55f * size.y(), top = size.z() + 0.15f;
  std::vector<Eigen::Vector3f> inside;
  for (const auto& p : scene.points) {
    const Eigen::Vector3f d = p - bottom;
    if (!(d.z() > 0.03f && d.z() < top)) continue;
    const float x = c * d.x() + s * d.y(), y = -s * d.x() + c * d.y();
    if (std::abs(x) < hx && std::abs(y) < hy) inside.emplace_back(x, y, d.z());
  }
  constexpr size_t kMinPoints = 10;
  if (inside.size() < kMinPoints) return 2.0f;
  const ShapeProfile measured = shapeProfile(inside, size);
  float nearest = 2.0f;
  for (const auto& t : trained) nearest = std::min(nearest, profileDistance(measured, t));
  return nearest;
}

// The measured points near a hypothesis, above the floor, for ICP's nearest-point pairing.
struct NearbyMeasured {
  std::vector<Eigen::Vector3f> points;
  NeighbourGrid grid;  // over `points`, cells of the ICP gate

  NearbyMeasured(const VerificationScene& scene, const Eigen::Vector3f& middle, float radius, float floor_z, float gate) {
    for (const auto& p : scene.points) {
      if ((p - middle).squaredNorm() <= radius * radius && p.z() >= floor_z + 0.03f) points.push_back(p);
    }
    if (!points.empty()) grid = NeighbourGrid(points, gate);
  }
};

// The shape points of `pose` the sensor would see: front-most in their pixel, and not behind a
// nearer measured surface. A map has no sensor: every point above the floor.
std::vector<int> visiblePoints(const VerificationScene& scene, const ShapeView& sv, const std::vector<Eigen::Vector3f>& shape,
                               int points, const Pose& pose, ShapeBuffer& buffer) {
  const int n = std::min<int>(points, static_cast<int>(shape.size()));
  std::vector<int> out;
  if (scene.map) {
    for (int i = 0; i < n; ++i) {
      if (shape[static_cast<size_t>(i)].z() >= 0.05f) out.push_back(i);
    }
    return out;
  }
  fillShapeBuffer(sv, shape, n, pose, 0.05f, buffer);  // not on the floor
  for (const int pixel : buffer.touched) {
    ShapeBuffer::Pixel& nearest = buffer.pixels[static_cast<size_t>(pixel)];
    const float measured = sv.view.depth[static_cast<size_t>(pixel)];
    if (std::isfinite(measured) && measured >= nearest.z - depthMargin(nearest.z, sv.margin)) out.push_back(nearest.index);
    nearest.index = -1;
  }
  return out;
}

// Up to `iterations` steps of ICP from `start`: the visible shape points paired with their nearest
// measured points, the turn about up and the shift along the floor that bring the pairs' horizontal
// positions closest (the 2D Procrustes solution), until a step moves the pose by under a
// millimetre and a tenth of a degree. Nothing when too few points pair up.
std::optional<Pose> alignByIcp(const VerificationScene& scene, const ShapeView& sv, const NearbyMeasured& measured,
                               const std::vector<Eigen::Vector3f>& shape, const Pose& start,
                               const VerificationParams& params, ShapeBuffer& buffer) {
  constexpr size_t kMinPairs = 20;
  if (measured.points.size() < kMinPairs) return std::nullopt;
  Pose pose = start;
  bool moved = false;
  for (int iteration = 0; iteration < params.icp_iterations; ++iteration) {
    const std::vector<int> visible = visiblePoints(scene, sv, shape, params.ranking_points, pose, buffer);
    const Eigen::Matrix3f turn = headingOf(pose);
    const Eigen::Vector3f offset(pose.xy.x(), pose.xy.y(), sv.floor_z);
    std::vector<std::pair<Eigen::Vector2f, Eigen::Vector2f>> pairs;  // (shape, measured), horizontal
    pairs.reserve(visible.size());
    for (const int i : visible) {
      const Eigen::Vector3f p = turn * shape[static_cast<size_t>(i)] + offset;
      const int q = measured.grid.nearest(p, params.icp_gate);
      if (q >= 0) pairs.emplace_back(p.head<2>(), measured.points[static_cast<size_t>(q)].head<2>());
    }
    if (pairs.size() < kMinPairs) break;
    Eigen::Vector2f a_mean = Eigen::Vector2f::Zero(), b_mean = Eigen::Vector2f::Zero();
    for (const auto& [a, b] : pairs) a_mean += a, b_mean += b;
    a_mean /= static_cast<float>(pairs.size());
    b_mean /= static_cast<float>(pairs.size());
    float cross = 0, dot = 0;
    for (const auto& [a, b] : pairs) {
      const Eigen::Vector2f u = a - a_mean, v = b - b_mean;
      dot += u.dot(v);
      cross += u.x() * v.y() - u.y() * v.x();
    }
    const float angle = std::atan2(cross, dot);
    Eigen::Matrix2f rotation;
    rotation << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
    const Eigen::Vector2f xy = rotation * (pose.xy - a_mean) + b_mean;
    const float step = (xy - pose.xy).norm();
    pose.yaw += angle;
    pose.xy = xy;
    moved = true;
    if (step < 1e-3f && std::abs(angle) < 0.002f) break;
  }
  if (!moved) return std::nullopt;
  return pose;
}

// verify, with the category's trainedProfiles worked out by the caller: once per category when
// many hypotheses are verified.
std::optional<Verification> verifyWith(const VerificationScene& scene, const CategoryModel& category,
                                       const std::vector<ShapeProfile>& profiles, const Hypothesis& hypothesis,
                                       const VerificationParams& params, const std::unordered_set<uint64_t>* claimed,
                                       std::unordered_set<uint64_t>* explained) {
  const SceneBox local = sceneBox(scene, hypothesis);
  const UprightBox& box = local.box;
  const Eigen::Vector3f& center = box.center;
  const float floor_z = local.floor_z;
  float reach = 0, height = 0, side = 0;  // the farthest any shape reaches from its middle; the tallest; the longest
  for (const auto& o : category.objects) {
    if (o.surface.empty()) continue;
    reach = std::max(reach, 0.5f * o.size.norm());
    height = std::max(height, o.size.z());
    side = std::max(side, o.size.head<2>().maxCoeff());
  }
  const float shift = std::max(params.min_shift, params.shift_fraction * side);
  const Eigen::Vector3f middle(center.x(), center.y(), floor_z + height / 2);
  const float radius = reach + static_cast<float>(params.coarse_steps) * shift + params.fine_shift + 0.1f;
  // A map is checked in 3D wherever its viewpoint stands, also beside or inside the hypothesis.
  const std::optional<LocalView> view = scene.map ? LocalView{} : lookAt(scene, middle, radius);
  if (!view) return std::nullopt;

  ShapeBuffer scratch(view->depth.size());
  const CellSet claimed_cells(claimed);
  const ShapeView sv{*view, floor_z, params.margin, claimed_cells, 0.05f, params.fit_terms};
  std::vector<std::pair<float, Pose>> coarse;
  std::vector<Eigen::Vector3f> turned;  // each heading's shape in the view, for all its shifts
  for (size_t o = 0; o < category.objects.size(); ++o) {
    const std::vector<Eigen::Vector3f>& shape = category.objects[o].surface;
    if (shape.empty()) continue;  // a shape calibration holds out
    for (int y = 0; y < params.coarse_yaws; ++y) {
      const float yaw = box.yaw + 2 * kPi * static_cast<float>(y) / static_cast<float>(params.coarse_yaws);
      if (!scene.map) {
        turnIntoView(*view, shape, std::min<int>(params.coarse_points, static_cast<int>(shape.size())),
                     Pose{static_cast<int>(o), yaw, Eigen::Vector2f::Zero()}, turned);
      }
      for (int dx = -params.coarse_steps; dx <= params.coarse_steps; ++dx) {
        for (int dy = -params.coarse_steps; dy <= params.coarse_steps; ++dy) {
          const Pose pose{static_cast<int>(o), yaw,
                          center.head<2>() + shift * Eigen::Vector2f(static_cast<float>(dx), static_cast<float>(dy))};
          const Agreement a = poseAgreement(scene, sv, shape, params.coarse_points, pose, scratch, nullptr, &turned);
          coarse.emplace_back(a.rank(), pose);
        }
      }
    }
  }
  const size_t keep = std::min<size_t>(coarse.size(), static_cast<size_t>(std::max(1, params.refined_poses)));
  std::partial_sort(coarse.begin(), coarse.begin() + static_cast<long>(keep), coarse.end(),
                    [](const auto& a, const auto& b) { return a.first > b.first; });
  // The refinement ranks poses alone; the best is described once, after it.
  Pose best_pose;
  float best_rank = -std::numeric_limits<float>::infinity();
  for (size_t k = 0; k < keep; ++k) {
    const Pose& start = coarse[k].second;
    for (int dyaw = -1; dyaw <= 1; ++dyaw) {
      for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
          const Pose pose{start.object, start.yaw + params.fine_yaw * static_cast<float>(dyaw),
                          start.xy + params.fine_shift * Eigen::Vector2f(static_cast<float>(dx), static_cast<float>(dy))};
          const Agreement a = poseAgreement(scene, sv, category.objects[static_cast<size_t>(pose.object)].surface,
                                            params.ranking_points, pose, scratch);
          if (a.rank() <= best_rank) continue;
          best_rank = a.rank();
          best_pose = pose;
        }
      }
    }
  }
  if (params.icp_iterations > 0) {
    const std::vector<Eigen::Vector3f>& shape = category.objects[static_cast<size_t>(best_pose.object)].surface;
    const NearbyMeasured measured(scene, middle, radius, floor_z, params.icp_gate);
    if (const std::optional<Pose> aligned = alignByIcp(scene, sv, measured, shape, best_pose, params, scratch)) {
      if (poseAgreement(scene, sv, shape, params.ranking_points, *aligned, scratch).rank() > best_rank) best_pose = *aligned;
    }
  }
  const TrainingObject& object = category.objects[static_cast<size_t>(best_pose.object)];
  const Agreement a = poseAgreement(scene, sv, object.surface, params.max_points, best_pose, scratch, explained);
  Verification best;
  best.seen = a.seen;
  best.consistent = a.consistent;
  best.claimed = a.claimed;
  best.object = best_pose.object;
  // The top part on its own, among the points the fit was scored on; a map's is not read.
  if (!scene.map && params.top_part > 0) {
    std::vector<Eigen::Vector3f> top;
    const size_t scored = std::min<size_t>(static_cast<size_t>(params.max_points), object.surface.size());
    for (size_t i = 0; i < scored; ++i) {
      if (object.surface[i].z() >= params.top_part * object.size.z()) top.push_back(object.surface[i]);
    }
    const Agreement t = poseAgreement(scene, sv, top, static_cast<int>(top.size()), best_pose, scratch);
    best.top_seen = t.seen;
    best.top_consistent = t.consistent;
  }
  best.yaw = std::remainder(best_pose.yaw, 2 * kPi);
  const Eigen::Vector3f fitted(best_pose.xy.x(), best_pose.xy.y(), floor_z + object.size.z() / 2);
  best.center = scene.origin + scene.to_gravity.transpose() * fitted;
  best.profile_distance = profileDistanceAt(scene, profiles, Eigen::Vector3f(best_pose.xy.x(), best_pose.xy.y(), floor_z),
                                            best_pose.yaw, object.size);
  return best;
}

}  // namespace

bool hasShapes(const CategoryModel& category) {
  return std::any_of(category.objects.begin(), category.objects.end(), [](const TrainingObject& o) { return !o.surface.empty(); });
}

std::optional<Verification> verify(const VerificationScene& scene, const CategoryModel& category,
                                   const Hypothesis& hypothesis, const VerificationParams& params,
                                   const std::unordered_set<uint64_t>* claimed, std::unordered_set<uint64_t>* explained) {
  if (!hasShapes(category)) return std::nullopt;
  return verifyWith(scene, category, trainedProfiles(category), hypothesis, params, claimed, explained);
}

void verifyHypotheses(const VerificationScene& scene, const Model& model, std::vector<Hypothesis>& hypotheses,
                      const VerificationParams& params, const ShouldStop& should_stop) {
  // Most confident first; per category, the surface each has explained.
  std::stable_sort(hypotheses.begin(), hypotheses.end(),
                   [](const Hypothesis& a, const Hypothesis& b) { return a.confidence > b.confidence; });
  std::map<std::string, std::unordered_set<uint64_t>> explained;
  std::map<std::string, std::vector<ShapeProfile>> profiles;
  for (auto& h : hypotheses) {
    throwIfStopped(should_stop, "verification");
    const CategoryModel* category = model.find(h.category);
    if (category == nullptr || !hasShapes(*category)) continue;
    std::unordered_set<uint64_t>& own = explained[h.category];
    std::unordered_set<uint64_t> mine;
    auto trained = profiles.find(h.category);
    if (trained == profiles.end()) trained = profiles.emplace(h.category, trainedProfiles(*category)).first;
    h.verification = verifyWith(scene, *category, trained->second, h, params, &own, &mine);
    own.insert(mine.begin(), mine.end());
    if (!h.verification) continue;
    h.verification->explained.assign(mine.begin(), mine.end());
    std::sort(h.verification->explained.begin(), h.verification->explained.end());
    UprightBox box;
    box.size = category->objects[static_cast<size_t>(h.verification->object)].size;
    box.yaw = h.verification->yaw;
    box.center = scene.to_gravity * h.verification->center;
    h.box = box.toScene(scene.to_gravity);
    h.upright_box = true;
  }
}

}  // namespace ism
