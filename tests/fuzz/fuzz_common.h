#pragma once
// Shared by the fuzz targets: what every decoded scene must satisfy, and the file round trip
// the PCD and PLY targets need because PCL reads clouds from paths only.
#include <pcl/console/print.h>
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/common/error.h"
#include "core/common/types.h"
#include "core/io/cloud_io.h"
#include "core/io/depth_png.h"
#include "core/io/file_bytes.h"

namespace ism::fuzz {

// The Scene contract (core/common/types.h) that recognition relies on without re-checking:
// finite points, and pixel indices that are inside the image and index-aligned with the cloud.
// A violation traps, so libFuzzer reports it as a crash with the input.
inline void checkScene(const Scene& scene) {
  if (!scene.cloud) __builtin_trap();
  for (const auto& p : scene.cloud->points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) __builtin_trap();
  }
  if (scene.pixel_index.empty()) return;
  if (scene.pixel_index.size() != scene.cloud->size()) __builtin_trap();
  const long pixels = static_cast<long>(scene.image_width) * scene.image_height;
  for (int index : scene.pixel_index) {
    if (index < 0 || index >= pixels) __builtin_trap();
  }
}

inline int loadCloudBytes(const uint8_t* data, size_t size, const char* extension) {
  // PCL logs every parse failure; at thousands of inputs per second that hides the findings.
  static const bool quiet = (pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS), true);
  (void)quiet;
  // One file per process: libFuzzer's -fork and -jobs run several.
  static const std::string path = "/tmp/ism_fuzz_" + std::to_string(getpid()) + extension;
  writeFileBytes(path, std::string(reinterpret_cast<const char*>(data), size));
  try {
    checkScene(loadCloudFile(path));
  } catch (const Error&) {
    // Rejecting malformed input with ism::Error is the contract; any other exception escapes
    // and libFuzzer reports it.
  }
  return 0;
}

}  // namespace ism::fuzz
