#include "client/cli/frame_source.h"

#include <OpenNI.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "core/io/file_bytes.h"
#include "proto/wire/messages.h"

namespace ism::client {
namespace fs = std::filesystem;
namespace {

class PngFolder final : public FrameSource {
 public:
  PngFolder(std::string directory, std::vector<fs::path> files, v1::CameraIntrinsics intrinsics)
      : directory_(std::move(directory)), files_(std::move(files)), intrinsics_(intrinsics) {}

  std::optional<SourceFrame> next() override {
    if (index_ >= files_.size()) return std::nullopt;
    const fs::path& file = files_[index_++];
    SourceFrame frame;
    frame.name = file.filename().string();
    auto* depth = frame.scene.mutable_depth();
    depth->set_encoding(v1::DEPTH_ENCODING_PNG);
    depth->set_data(readFileBytes(file.string()));
    *depth->mutable_intrinsics() = intrinsics_;
    // TUM names frames by their capture time in seconds ("1305031102.160407.png").
    try {
      frame.timestamp_us = static_cast<int64_t>(std::stod(file.stem().string()) * 1e6);
    } catch (const std::exception&) {
      frame.timestamp_us = 0;
    }
    return frame;
  }

  std::string describe() const override {
    return std::to_string(files_.size()) + " depth PNGs in " + directory_;
  }

 private:
  std::string directory_;
  std::vector<fs::path> files_;
  v1::CameraIntrinsics intrinsics_;
  size_t index_ = 0;
};

void check(openni::Status status, const std::string& what) {
  if (status != openni::STATUS_OK) {
    throw std::runtime_error(what + ": " + openni::OpenNI::getExtendedError());
  }
}

class OpenNiSource final : public FrameSource {
 public:
  explicit OpenNiSource(const std::string& uri) {
    check(openni::OpenNI::initialize(), "OpenNI2 initialisation failed");
    const bool recording = uri.size() > 4 && uri.compare(uri.size() - 4, 4, ".oni") == 0;
    if (!recording && uri.empty()) {
      openni::Array<openni::DeviceInfo> devices;
      openni::OpenNI::enumerateDevices(&devices);
      if (devices.getSize() == 0) {
        throw std::runtime_error("no OpenNI2 depth sensor is attached (check the USB cable and permissions), "
                                 "or stream a recording with --device FILE.oni or a --folder of depth PNGs");
      }
    }
    check(device_.open(uri.empty() ? openni::ANY_DEVICE : uri.c_str()),
          "cannot open " + (uri.empty() ? std::string("the OpenNI2 sensor") : uri));
    if (recording) {
      // A recording is played once, as fast as it can be read: the stream's own backpressure
      // decides which frames are recognised.
      device_.getPlaybackControl()->setRepeatEnabled(false);
      device_.getPlaybackControl()->setSpeed(-1.0f);
    }
    check(depth_.create(device_, openni::SENSOR_DEPTH), "the device has no depth stream");
    check(depth_.start(), "cannot start the depth stream");
    if (recording) remaining_ = device_.getPlaybackControl()->getNumberOfFrames(depth_);
    description_ = recording ? "recording " + uri : std::string("OpenNI2 sensor ") + device_.getDeviceInfo().getName();
  }

  ~OpenNiSource() override {
    depth_.stop();
    depth_.destroy();
    device_.close();
    openni::OpenNI::shutdown();
  }

  std::optional<SourceFrame> next() override {
    if (remaining_ == 0) return std::nullopt;
    openni::VideoStream* streams[] = {&depth_};
    int ready = 0;
    if (openni::OpenNI::waitForAnyStream(streams, 1, &ready, 5000) != openni::STATUS_OK) {
      if (remaining_ > 0) return std::nullopt;  // a recording ran out
      throw std::runtime_error("the sensor sent no depth frame for 5 s: " +
                               std::string(openni::OpenNI::getExtendedError()));
    }
    openni::VideoFrameRef frame;
    check(depth_.readFrame(&frame), "cannot read a depth frame");
    if (remaining_ > 0) --remaining_;
    const auto format = frame.getVideoMode().getPixelFormat();
    if (format != openni::PIXEL_FORMAT_DEPTH_1_MM && format != openni::PIXEL_FORMAT_DEPTH_100_UM) {
      throw std::runtime_error("unsupported OpenNI2 depth pixel format " + std::to_string(format));
    }
    const int width = frame.getWidth(), height = frame.getHeight();
    SourceFrame out;
    out.name = "frame " + std::to_string(frame.getFrameIndex());
    out.timestamp_us = static_cast<int64_t>(frame.getTimestamp());
    auto* depth = out.scene.mutable_depth();
    depth->set_encoding(v1::DEPTH_ENCODING_RAW_UINT16_LE);
    depth->set_width(width);
    depth->set_height(height);
    // Rows may be padded: copy them one by one into the packed layout of the wire format.
    std::string* data = depth->mutable_data();
    data->resize(size_t(width) * height * 2);
    const auto* src = static_cast<const char*>(frame.getData());
    for (int row = 0; row < height; ++row) {
      std::copy_n(src + size_t(row) * frame.getStrideInBytes(), width * 2, data->data() + size_t(row) * width * 2);
    }
    DepthIntrinsics k;
    k.fx = width / (2.0f * std::tan(depth_.getHorizontalFieldOfView() / 2));
    k.fy = height / (2.0f * std::tan(depth_.getVerticalFieldOfView() / 2));
    k.cx = width / 2.0f - 0.5f;
    k.cy = height / 2.0f - 0.5f;
    k.depth_scale = format == openni::PIXEL_FORMAT_DEPTH_1_MM ? 1000.0f : 10000.0f;
    *depth->mutable_intrinsics() = wire::intrinsicsToProto(k);
    return out;
  }

  std::string describe() const override { return description_; }

 private:
  openni::Device device_;
  openni::VideoStream depth_;
  int remaining_ = -1;  // frames left in a recording; -1 for a live sensor
  std::string description_;
};

}  // namespace

std::unique_ptr<FrameSource> openPngFolder(const std::string& directory, const DepthIntrinsics& intrinsics) {
  v1::CameraIntrinsics message = wire::intrinsicsToProto(intrinsics);
  wire::intrinsicsFromProto(message, "intrinsics");  // a wrong flag fails before any frame is sent
  fs::path root = fs::is_directory(fs::path(directory) / "depth") ? fs::path(directory) / "depth" : fs::path(directory);
  if (!fs::is_directory(root)) throw std::runtime_error(directory + " is not a directory");
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(root)) {
    if (entry.is_regular_file() && entry.path().extension() == ".png") files.push_back(entry.path());
  }
  if (files.empty()) throw std::runtime_error("no .png files in " + root.string());
  std::sort(files.begin(), files.end());
  return std::make_unique<PngFolder>(root.string(), std::move(files), std::move(message));
}

std::unique_ptr<FrameSource> openOpenNi(const std::string& uri) { return std::make_unique<OpenNiSource>(uri); }

}  // namespace ism::client
