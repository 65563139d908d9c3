#pragma once
// A map's surfaces for the scene checks' tests: points every 5 cm, as a fused room holds them.
#include <vector>

#include <Eigen/Core>

namespace ism::testing {

// The horizontal rectangle [x0, x1] x [y0, y1] at height z.
inline void plate(std::vector<Eigen::Vector3f>& points, float x0, float x1, float y0, float y1, float z) {
  for (float x = x0; x <= x1 + 1e-4f; x += 0.05f) {
    for (float y = y0; y <= y1 + 1e-4f; y += 0.05f) points.emplace_back(x, y, z);
  }
}

// The vertical rectangle [x0, x1] x [z0, z1] at depth y.
inline void wall(std::vector<Eigen::Vector3f>& points, float x0, float x1, float y, float z0, float z1) {
  for (float x = x0; x <= x1 + 1e-4f; x += 0.05f) {
    for (float z = z0; z <= z1 + 1e-4f; z += 0.05f) points.emplace_back(x, y, z);
  }
}

// A couch's top surfaces, 2 x 0.9 m about x = 0, its front at y - 0.45 m: a seat at 0.45 m over the
// front 0.65 m, the back's top at 0.85 m, arms to 0.65 m.
inline void couchTop(std::vector<Eigen::Vector3f>& points, float y) {
  plate(points, -0.85f, 0.85f, y - 0.45f, y + 0.2f, 0.45f);  // the seat
  plate(points, -1.0f, 1.0f, y + 0.2f, y + 0.45f, 0.85f);    // the back's top
  plate(points, -1.0f, -0.85f, y - 0.45f, y + 0.2f, 0.65f);  // the arms
  plate(points, 0.85f, 1.0f, y - 0.45f, y + 0.2f, 0.65f);
}

}  // namespace ism::testing
