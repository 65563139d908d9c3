#include "tests/common/synthetic_furniture.h"

#include <cmath>
#include <cstdint>

#include "core/common/error.h"

namespace ism::testing {
namespace {

// Deterministic proportion change in [-5%, +5%] per (variant, dimension); variant 0 is nominal.
float vary(int variant, int dimension) {
  if (variant == 0) return 1.0f;
  uint32_t h = static_cast<uint32_t>(variant) * 2654435761u ^ static_cast<uint32_t>(dimension + 1) * 2246822519u;
  h ^= h >> 15;
  h *= 2246822519u;
  h ^= h >> 13;
  return 1.0f + 0.1f * (static_cast<float>(h % 1001) / 1000.0f - 0.5f);
}

Mesh box(float x0, float y0, float z0, float x1, float y1, float z1) {
  return boxMesh(Eigen::Vector3f(x0, y0, z0), Eigen::Vector3f(x1, y1, z1));
}

// Four square legs of side `leg`, inset `inset` from the corners of a w x d footprint.
Mesh legs(float w, float d, float leg, float inset, float height) {
  Mesh out;
  for (float sx : {-1.0f, 1.0f}) {
    for (float sy : {-1.0f, 1.0f}) {
      const float cx = sx * (w / 2 - inset - leg / 2), cy = sy * (d / 2 - inset - leg / 2);
      out = merge(out, box(cx - leg / 2, cy - leg / 2, 0, cx + leg / 2, cy + leg / 2, height));
    }
  }
  return out;
}

// Placed meshes face -y (see placeMesh), so backs are at +y.
Mesh diningTable(int v) {
  const float w = 1.2f * vary(v, 0), d = 0.8f * vary(v, 1), h = 0.75f * vary(v, 2), top = 0.04f * vary(v, 3);
  return merge(box(-w / 2, -d / 2, h - top, w / 2, d / 2, h), legs(w, d, 0.06f * vary(v, 4), 0.05f, h - top));
}

Mesh diningChair(int v) {
  const float w = 0.45f * vary(v, 0), d = 0.5f * vary(v, 1), h = 0.9f * vary(v, 2);
  const float seat_z = 0.45f * vary(v, 3), seat = 0.04f, back = 0.04f * vary(v, 4);
  Mesh chair = merge(box(-w / 2, -d / 2, seat_z - seat, w / 2, d / 2, seat_z), legs(w, d, 0.04f, 0.0f, seat_z - seat));
  return merge(chair, box(-w / 2, d / 2 - back, seat_z, w / 2, d / 2, h));
}

Mesh officeChair(int v) {
  const float w = 0.48f * vary(v, 0), d = 0.46f * vary(v, 1), h = 0.95f * vary(v, 2);
  const float seat_z = 0.5f * vary(v, 3), seat = 0.06f, arm = 0.28f * vary(v, 4), column = 0.05f;
  Mesh chair = box(-w / 2, -d / 2, seat_z - seat, w / 2, d / 2, seat_z);
  chair = merge(chair, box(-column / 2, -column / 2, 0.05f, column / 2, column / 2, seat_z - seat));
  for (int k = 0; k < 5; ++k) {  // star base: five thin arms radiating from the column
    const Eigen::Isometry3f spoke(Eigen::AngleAxisf(static_cast<float>(M_PI) / 2 + k * 2 * static_cast<float>(M_PI) / 5,
                                                    Eigen::Vector3f::UnitZ()));
    chair = merge(chair, transformed(box(0, -0.02f, 0, arm, 0.02f, 0.05f), spoke));
  }
  const float back_y = d / 2 - 0.03f;
  chair = merge(chair, box(-0.025f, back_y - 0.03f, seat_z, 0.025f, back_y, seat_z + 0.1f));  // back support bar
  return merge(chair, box(-0.44f * w, back_y, seat_z + 0.05f, 0.44f * w, back_y + 0.04f, h));
}

Mesh couch(int v) {
  const float w = 1.9f * vary(v, 0), d = 0.85f * vary(v, 1), h = 0.8f * vary(v, 2);
  const float seat_z = 0.42f * vary(v, 3), arm_w = 0.18f * vary(v, 4), arm_h = 0.6f * vary(v, 5), back = 0.2f;
  Mesh sofa = box(-w / 2, -d / 2, 0, w / 2, d / 2, seat_z);
  sofa = merge(sofa, box(-w / 2, d / 2 - back, 0, w / 2, d / 2, h));
  sofa = merge(sofa, box(-w / 2, -d / 2, 0, -w / 2 + arm_w, d / 2, arm_h));
  return merge(sofa, box(w / 2 - arm_w, -d / 2, 0, w / 2, d / 2, arm_h));
}

}  // namespace

Mesh boxMesh(const Eigen::Vector3f& min_corner, const Eigen::Vector3f& max_corner) {
  Mesh mesh;
  for (int i = 0; i < 8; ++i) {  // bit 0 = x, bit 1 = y, bit 2 = z
    mesh.vertices.emplace_back(i & 1 ? max_corner.x() : min_corner.x(), i & 2 ? max_corner.y() : min_corner.y(),
                               i & 4 ? max_corner.z() : min_corner.z());
  }
  // Outward-facing (counter-clockwise seen from outside).
  mesh.triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                    {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  return mesh;
}

Mesh merge(const Mesh& a, const Mesh& b) {
  Mesh out = a;
  const int offset = static_cast<int>(a.vertices.size());
  out.vertices.insert(out.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (const auto& t : b.triangles) out.triangles.push_back(t + Eigen::Vector3i::Constant(offset));
  return out;
}

std::vector<Eigen::Vector3f> boxSurface(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
  std::vector<Eigen::Vector3f> points;
  for (float x = lo.x(); x <= hi.x() + 1e-4f; x += 0.04f) {
    for (float y = lo.y(); y <= hi.y() + 1e-4f; y += 0.04f) {
      for (float z = lo.z(); z <= hi.z() + 1e-4f; z += 0.04f) {
        const int on_faces = (x - lo.x() < 0.04f || hi.x() - x < 0.04f) + (y - lo.y() < 0.04f || hi.y() - y < 0.04f) +
                             (z - lo.z() < 0.04f || hi.z() - z < 0.04f);
        if (on_faces > 0) points.emplace_back(x, y, z);
      }
    }
  }
  return points;
}

Mesh syntheticFurniture(const std::string& category, int variant) {
  Mesh mesh;
  if (category == "dining_table") mesh = diningTable(variant);
  else if (category == "dining_chair") mesh = diningChair(variant);
  else if (category == "office_chair") mesh = officeChair(variant);
  else if (category == "couch") mesh = couch(variant);
  else {
    throw Error(ErrorCode::kInvalidInput, "syntheticFurniture: unknown category '" + category +
                                              "' (dining_table, dining_chair, office_chair, couch)");
  }
  MeshPlacement already_z_up;
  already_z_up.up = UpAxis::kZ;
  return placeMesh(mesh, already_z_up);  // re-centres the asymmetric star base
}

}  // namespace ism::testing
