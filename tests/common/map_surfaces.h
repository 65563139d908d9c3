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

}  // namespace ism::testing
