#include "core/common/upright_box.h"
#include "core/common/gravity_frame.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace ism {
namespace {

using Point2 = Eigen::Vector2f;

std::array<Point2, 4> footprint(const UprightBox& box) {
  const Eigen::Rotation2Df r(box.yaw);
  const float hx = box.size.x() / 2, hy = box.size.y() / 2;
  const Point2 c = box.center.head<2>();
  // Counter-clockwise, as the clipping below expects.
  return {c + r * Point2(-hx, -hy), c + r * Point2(hx, -hy), c + r * Point2(hx, hy), c + r * Point2(-hx, hy)};
}

float cross(const Point2& a, const Point2& b) { return a.x() * b.y() - a.y() * b.x(); }

// Sutherland-Hodgman: `subject` clipped by each edge of the convex, counter-clockwise `clip`.
std::vector<Point2> clipConvex(std::vector<Point2> subject, const std::array<Point2, 4>& clip) {
  for (size_t e = 0; e < clip.size() && !subject.empty(); ++e) {
    const Point2& a = clip[e];
    const Point2& b = clip[(e + 1) % clip.size()];
    const auto inside = [&](const Point2& p) { return cross(b - a, p - a) >= 0; };
    std::vector<Point2> out;
    for (size_t i = 0; i < subject.size(); ++i) {
      const Point2& p = subject[i];
      const Point2& q = subject[(i + 1) % subject.size()];
      const bool p_in = inside(p), q_in = inside(q);
      if (p_in) out.push_back(p);
      if (p_in != q_in) {
        const float dp = cross(b - a, p - a), dq = cross(b - a, q - a);
        out.push_back(p + (q - p) * (dp / (dp - dq)));
      }
    }
    subject = std::move(out);
  }
  return subject;
}

float area(const std::vector<Point2>& polygon) {
  float twice = 0;
  for (size_t i = 0; i < polygon.size(); ++i) twice += cross(polygon[i], polygon[(i + 1) % polygon.size()]);
  return std::abs(twice) / 2;
}

}  // namespace

const char* toString(UpSource source) {
  switch (source) {
    case UpSource::kGiven:
      return "given";
    case UpSource::kFloor:
      return "floor";
    case UpSource::kAssumed:
      return "assumed";
  }
  return "?";
}

Eigen::Matrix3f gravityRotation(const Eigen::Vector3f& up) {
  const Eigen::Vector3f z = up.normalized();
  Eigen::Vector3f x = Eigen::Vector3f::UnitX() - z * z.x();
  if (x.norm() < 0.3f) x = Eigen::Vector3f::UnitY() - z * z.y();
  x.normalize();
  Eigen::Matrix3f r;
  r.row(0) = x.transpose();
  r.row(1) = z.cross(x).transpose();
  r.row(2) = z.transpose();
  return r;
}

OrientedBox UprightBox::toScene(const Eigen::Matrix3f& to_gravity) const {
  OrientedBox box;
  box.center = to_gravity.transpose() * center;
  box.size = size;
  const Eigen::Matrix3f axes = to_gravity.transpose() * Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  box.rotation = Eigen::Quaternionf(axes).normalized();
  return box;
}

bool insideFootprint(const Eigen::Vector3f& p, const UprightBox& box) {
  const Eigen::Vector2f local = Eigen::Rotation2Df(-box.yaw) * (p.head<2>() - box.center.head<2>());
  return std::abs(local.x()) <= box.size.x() / 2 && std::abs(local.y()) <= box.size.y() / 2;
}

UprightBox uprightBoxOf(const OrientedBox& box, const Eigen::Matrix3f& to_gravity) {
  const Eigen::Matrix3f axes = to_gravity * box.rotation.toRotationMatrix();
  int horizontal = 0;
  for (int a = 1; a < 3; ++a) {
    if (std::abs(axes(2, a)) < std::abs(axes(2, horizontal))) horizontal = a;
  }
  UprightBox out;
  out.yaw = std::atan2(axes(1, horizontal), axes(0, horizontal));
  const Eigen::Matrix3f yawed = Eigen::AngleAxisf(out.yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  const Eigen::Vector3f centre = to_gravity * box.center;
  // Half extents of the corners along the yawed axes: sum over the box axes of |projection|.
  const Eigen::Matrix3f in_yawed = yawed.transpose() * axes;
  out.size = 2 * (in_yawed.cwiseAbs() * (box.size / 2));
  out.center = centre;
  return out;
}

float footprintOverlap(const UprightBox& a, const UprightBox& b) {
  // Footprints farther apart than their half-diagonals reach have no overlap for the clipping to
  // find (it would return no polygon): most pairs of a room's hypotheses. The margin keeps the
  // clipping's rounding on the near side of this test.
  const float reach = 0.5f * (a.size.head<2>().norm() + b.size.head<2>().norm());
  if ((a.center.head<2>() - b.center.head<2>()).norm() > 1.001f * reach + 1e-4f) return 0;
  const auto fa = footprint(a);
  const auto fb = footprint(b);
  return area(clipConvex({fa.begin(), fa.end()}, fb));
}

float intersectionOverUnion(const UprightBox& a, const UprightBox& b) {
  const float va = a.volume(), vb = b.volume();
  if (!(va > 0) || !(vb > 0)) return 0;
  const float bottom = std::max(a.center.z() - a.size.z() / 2, b.center.z() - b.size.z() / 2);
  const float top = std::min(a.center.z() + a.size.z() / 2, b.center.z() + b.size.z() / 2);
  if (!(top > bottom)) return 0;
  const float overlap = footprintOverlap(a, b) * (top - bottom);
  return overlap / (va + vb - overlap);
}

}  // namespace ism
