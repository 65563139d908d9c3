#pragma once
// Internal to core/io: the one loop every reader (packed clouds, depth images, PCD, PLY) ends in,
// so that all of them drop the same points and keep pixel indices the same way.
#include <cmath>
#include <string>

#include "core/common/error.h"
#include "core/common/types.h"

namespace ism::io_detail {

inline bool isFinite(const PointT& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

// Builds a scene from `count` candidate points, keeping the finite ones. `fill(i, point)` writes
// candidate i. Organized input (height > 1) keeps its size and each kept point's pixel index.
template <class Fill>
Scene collectFinite(size_t count, int width, int height, bool has_color, const std::string& source, Fill fill,
                    Scene* reuse = nullptr) {
  Scene scene;
  if (reuse != nullptr) {
    if (reuse->cloud) scene.cloud = std::move(reuse->cloud);
    scene.pixel_index = std::move(reuse->pixel_index);
    scene.cloud->clear();
    scene.pixel_index.clear();
  }
  scene.source = source;
  scene.has_color = has_color;
  const bool organized = height > 1;
  if (organized) {
    scene.image_width = width;
    scene.image_height = height;
    scene.pixel_index.reserve(count);
  }
  auto& points = scene.cloud->points;
  points.reserve(count);
  PointT point;
  for (size_t i = 0; i < count; ++i) {
    fill(i, point);
    if (!isFinite(point)) continue;
    points.push_back(point);
    if (organized) scene.pixel_index.push_back(static_cast<int>(i));
  }
  if (points.empty()) {
    throw Error(ErrorCode::kInvalidInput,
                source + ": none of its " + std::to_string(count) + " points is finite (no valid measurement)");
  }
  scene.cloud->width = static_cast<uint32_t>(points.size());
  scene.cloud->height = 1;
  scene.cloud->is_dense = true;
  return scene;
}

}  // namespace ism::io_detail
