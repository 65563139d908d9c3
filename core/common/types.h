#pragma once
// The small types that flow between pipeline stages. PCL clouds are used inside stages;
// these structs are what a stage hands to the next one.
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/common/gravity_frame.h"
#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace ism {

using PointT = pcl::PointXYZRGB;
using Cloud = pcl::PointCloud<PointT>;
// Points without colour or normals: the downsampled and smoothed scene the front end works on.
using XyzCloud = pcl::PointCloud<pcl::PointXYZ>;
// Downsampled points with their normals: the search surface of SHOT and of the boundary test.
using Surface = pcl::PointCloud<pcl::PointNormal>;

// A pinhole camera's focal lengths and principal point, in pixels. The defaults are the Kinect's
// 640x480 depth camera, which the virtual scanner imitates.
struct PinholeIntrinsics {
  float fx = 525.0f;
  float fy = 525.0f;
  float cx = 319.5f;
  float cy = 239.5f;
};

// A pinhole camera with its image size: the virtual scanner's sensor, the picture's viewpoint.
struct CameraIntrinsics : PinholeIntrinsics {
  int width = 640;
  int height = 480;
};

// One sensor frame (or a whole reconstructed room) ready for the front end.
struct Scene {
  // Finite points only: loaders drop NaN/Inf. Never null after loading.
  Cloud::Ptr cloud{new Cloud};
  bool has_color = false;
  // Where the sensor was, in the cloud's frame. Normals are oriented towards it.
  Eigen::Vector3f sensor_origin = Eigen::Vector3f::Zero();
  Eigen::Quaternionf sensor_orientation = Eigen::Quaternionf::Identity();
  // When the input was organized (an image), its size and, per kept point, its pixel index
  // (row * image_width + col). Empty when the input was unorganized.
  int image_width = 0;
  int image_height = 0;
  std::vector<int> pixel_index;
  std::string source;  // file name or "request", for messages
  // Up in the cloud's frame when the caller knows it (a robot's TF, an accelerometer, a
  // gravity-levelled room scan); otherwise the gravity stage looks for the floor.
  std::optional<Eigen::Vector3f> up;
};

// Rows are descriptors (352 floats for SHOT); row-major so FLANN can index it in place.
using DescriptorMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Keypoints that survived description, index-aligned: positions[i], lrfs[i], descriptors.row(i).
struct Features {
  std::vector<Eigen::Vector3f> positions;
  // Rows are the x, y, z axes of the keypoint's local reference frame, in scene coordinates:
  // lrf * v turns a scene vector into LRF coordinates, lrf.transpose() * v turns it back.
  std::vector<Eigen::Matrix3f> lrfs;
  DescriptorMatrix descriptors;
  // From the gravity stage, when the front end ran it: up and the floor, and per keypoint its
  // height above the floor (when there is one), its surface normal turned towards the sensor and
  // the direction from it to the centroid of its support (what upright vote frames are made of).
  std::optional<Gravity> gravity;
  std::vector<float> heights;
  std::vector<Eigen::Vector3f> normals;
  std::vector<Eigen::Vector3f> support_directions;
  // Made from a scene with an image grid (a depth frame), not from an unorganized cloud: the two
  // reach different scores for the same furniture, so the model may calibrate them apart.
  bool organized = false;
  size_t size() const { return positions.size(); }
};

// Per-stage wall-clock times in milliseconds, in pipeline order.
struct StageTimings {
  std::vector<std::pair<std::string, double>> stages;
  void add(const std::string& name, double ms) { stages.emplace_back(name, ms); }
  double total() const {
    double t = 0;
    for (const auto& s : stages) t += s.second;
    return t;
  }
};

// Measures one stage and records it on destruction.
class ScopedStage {
 public:
  ScopedStage(StageTimings* timings, std::string name)
      : timings_(timings), name_(std::move(name)), start_(std::chrono::steady_clock::now()) {}
  ~ScopedStage() {
    if (timings_ == nullptr) return;
    auto ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
    timings_->add(name_, ms);
  }
  ScopedStage(const ScopedStage&) = delete;
  ScopedStage& operator=(const ScopedStage&) = delete;

 private:
  StageTimings* timings_;
  std::string name_;
  std::chrono::steady_clock::time_point start_;
};

// Polled between stages and inside long loops, also from several threads at once; returning
// true makes the pipeline throw Error(kCancelled). The service wires it to the call's deadline
// and cancellation.
using ShouldStop = std::function<bool()>;
void throwIfStopped(const ShouldStop& should_stop, const char* where);

// An oriented bounding box: rotation's columns are the box axes, size is the extent along them.
struct OrientedBox {
  Eigen::Vector3f center = Eigen::Vector3f::Zero();
  Eigen::Vector3f size = Eigen::Vector3f::Zero();
  Eigen::Quaternionf rotation = Eigen::Quaternionf::Identity();
  float volume() const { return size.x() * size.y() * size.z(); }
  float longestEdge() const { return size.maxCoeff(); }
};

}  // namespace ism
