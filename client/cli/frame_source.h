#pragma once
// Depth frames for `ism-client stream`: an OpenNI2 sensor, an .oni recording (through
// OpenNI2), or a folder of 16-bit depth PNGs (TUM RGB-D layout or plain). Every source yields
// ready-to-send Scene messages, so the stream loop does not care where frames come from.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "core/io/cloud_io.h"
#include "ism/v1/service.pb.h"

namespace ism::client {

struct SourceFrame {
  v1::Scene scene;
  int64_t timestamp_us = 0;
  std::string name;  // file name or "frame N"
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual std::optional<SourceFrame> next() = 0;  // nullopt at the end
  virtual std::string describe() const = 0;
};

// depth/*.png when DIR/depth exists (TUM RGB-D), else DIR/*.png; sorted by name. The PNG
// bytes are sent as they are. Throws std::runtime_error when there is no PNG, ism::Error when the
// intrinsics are not valid.
std::unique_ptr<FrameSource> openPngFolder(const std::string& directory, const DepthIntrinsics& intrinsics);

// `uri` empty: the first sensor found; a path ending in .oni: that recording. Intrinsics come
// from the device's field of view and depth units. Throws std::runtime_error with OpenNI2's
// message when no device is attached or the file cannot be opened.
std::unique_ptr<FrameSource> openOpenNi(const std::string& uri);

}  // namespace ism::client
