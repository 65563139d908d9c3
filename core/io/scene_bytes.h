#pragma once
// Scenes from bytes in memory: packed float32 clouds and 16-bit depth images (raw or PNG), as
// they arrive over the wire. Needs libpng and zlib only, no PCL I/O: this is all of core/io the
// server links (the PCD and PLY files of cloud_io.h pull pcl_io, and with it VTK, Qt and
// OpenNI). NaN/Inf points are dropped. Every failure throws ism::Error whose message names the
// source (file or "request") and the problem.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/common/types.h"

namespace ism {

struct DepthIntrinsics : PinholeIntrinsics {
  // Raw depth units per metre: 1000 for OpenNI millimetres, 5000 for TUM RGB-D PNGs.
  float depth_scale = 1000.0f;
};

// Raw row-major uint16 depth (0 = no measurement) -> organized scene in the camera frame
// (x right, y down, z forward), sensor at the origin.
Scene depthToScene(const uint16_t* depth, int width, int height, const DepthIntrinsics& intrinsics,
                   const std::string& source = "depth image");

// A 16-bit single-channel PNG (file or bytes in memory) -> scene, as depthToScene.
Scene loadDepthPng(const std::string& path, const DepthIntrinsics& intrinsics);
// `should_stop` as decodeDepthPng16 uses it: long decodes end when the caller gives up.
Scene decodeDepthPng(const std::string& png_bytes, const DepthIntrinsics& intrinsics,
                     const std::string& source = "depth PNG", const ShouldStop& should_stop = {});

// Packed float32 xyz (and optional packed uint8 rgb) as sent over the wire. width*height must
// equal the point count when organized (height > 1), else pass width = count, height = 1. `xyz`
// need not be aligned (protobuf's bytes fields are not): it is read through memcpy, so callers
// need no aligned copy. With `reuse`, its cloud and pixel indices are cleared and refilled, so
// that a server worker decoding frame after frame keeps their allocations.
Scene sceneFromPacked(const void* xyz, size_t count, const uint8_t* rgb, int width, int height,
                      const std::string& source = "request", Scene* reuse = nullptr);

}  // namespace ism
