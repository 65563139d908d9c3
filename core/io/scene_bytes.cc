#include "core/io/scene_bytes.h"

#include <cmath>
#include <cstring>
#include <limits>

#include "core/common/error.h"
#include "core/io/depth_png.h"
#include "core/io/file_bytes.h"
#include "core/io/finite_points.h"

namespace ism {

using io_detail::collectFinite;

Scene depthToScene(const uint16_t* depth, int width, int height, const DepthIntrinsics& intrinsics,
                   const std::string& source) {
  if (depth == nullptr || width <= 0 || height <= 0) {
    throw Error(ErrorCode::kInvalidInput, source + ": empty depth image (" + std::to_string(width) + "x" +
                                              std::to_string(height) + ")");
  }
  const auto positive = [](float v) { return std::isfinite(v) && v > 0.0f; };
  if (!positive(intrinsics.fx) || !positive(intrinsics.fy) || !positive(intrinsics.depth_scale) ||
      !std::isfinite(intrinsics.cx) || !std::isfinite(intrinsics.cy)) {
    throw Error(ErrorCode::kInvalidInput,
                source + ": invalid intrinsics fx=" + std::to_string(intrinsics.fx) + " fy=" +
                    std::to_string(intrinsics.fy) + " cx=" + std::to_string(intrinsics.cx) + " cy=" +
                    std::to_string(intrinsics.cy) + " depth_scale=" + std::to_string(intrinsics.depth_scale) +
                    " (focal lengths and scale must be positive)");
  }
  const float inv_fx = 1.0f / intrinsics.fx, inv_fy = 1.0f / intrinsics.fy;
  const float inv_scale = 1.0f / intrinsics.depth_scale;
  const size_t count = static_cast<size_t>(width) * height;
  return collectFinite(count, width, height, false, source, [&](size_t i, PointT& p) {
    const uint16_t raw = depth[i];
    if (raw == 0) {
      p.z = std::numeric_limits<float>::quiet_NaN();
      return;
    }
    const float u = static_cast<float>(i % width), v = static_cast<float>(i / width);
    p.z = raw * inv_scale;
    p.x = (u - intrinsics.cx) * p.z * inv_fx;
    p.y = (v - intrinsics.cy) * p.z * inv_fy;
  });
}

Scene decodeDepthPng(const std::string& png_bytes, const DepthIntrinsics& intrinsics, const std::string& source,
                     const ShouldStop& should_stop) {
  const DepthPng image = decodeDepthPng16(png_bytes, source, should_stop);
  return depthToScene(image.pixels.data(), image.width, image.height, intrinsics, source);
}

Scene loadDepthPng(const std::string& path, const DepthIntrinsics& intrinsics) {
  return decodeDepthPng(readFileBytes(path), intrinsics, path);
}

Scene sceneFromPacked(const void* xyz, size_t count, const uint8_t* rgb, int width, int height,
                      const std::string& source, Scene* reuse) {
  if (count == 0 || xyz == nullptr) throw Error(ErrorCode::kInvalidInput, source + ": no points");
  if (width <= 0 || height <= 0) {
    throw Error(ErrorCode::kInvalidInput, source + ": width " + std::to_string(width) + " and height " +
                                              std::to_string(height) + " must be positive");
  }
  if (static_cast<size_t>(width) * height != count) {
    throw Error(ErrorCode::kInvalidInput, source + ": width*height = " + std::to_string(width) + "*" +
                                              std::to_string(height) + " = " +
                                              std::to_string(static_cast<size_t>(width) * height) +
                                              " does not match the " + std::to_string(count) + " points sent");
  }
  const auto* bytes = static_cast<const char*>(xyz);
  return collectFinite(
      count, width, height, rgb != nullptr, source,
      [&](size_t i, PointT& p) {
        float v[3];
        std::memcpy(v, bytes + 12 * i, sizeof v);
        p.x = v[0];
        p.y = v[1];
        p.z = v[2];
        if (rgb != nullptr) {
          p.r = rgb[3 * i];
          p.g = rgb[3 * i + 1];
          p.b = rgb[3 * i + 2];
        }
      },
      reuse);
}

}  // namespace ism
