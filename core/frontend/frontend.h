#pragma once
// The front end: cloud -> downsampled surface with normals -> boundary keypoints ->
// SHOT descriptors with LRFs. Each stage is a free function with typed input, output and
// parameter struct, testable alone; extractFeatures() chains them.
#include <vector>

#include "core/common/types.h"
#include "core/frontend/params.h"

namespace ism {

using XyzCloud = pcl::PointCloud<pcl::PointXYZ>;

// Voxel-grid centroid downsampling.
XyzCloud::Ptr downsample(const Cloud& cloud, const DownsampleParams& params);

// Moving Least Squares smoothing (points are moved onto the fitted surface).
XyzCloud::Ptr smooth(const XyzCloud& cloud, const SmoothingParams& params);

// PCA normals, flipped towards `viewpoint`. Points whose normal is undefined are removed.
Surface::Ptr estimateNormals(const XyzCloud& cloud, const NormalParams& params,
                             const Eigen::Vector3f& viewpoint);

// Indices into `surface` of boundary points (largest angular gap > threshold).
std::vector<int> detectBoundaryKeypoints(const Surface& surface, const KeypointParams& params);

// SHOT (352-d, unit length) and its LRF at each keypoint, the whole surface as support.
// Keypoints with an undefined LRF or descriptor (too few neighbours, NaN) are dropped.
Features describe(const Surface& surface, const std::vector<int>& keypoints, const ShotParams& params);

struct FrontEndResult {
  Surface::Ptr surface;  // downsampled (and smoothed) points with normals
  Features features;     // described keypoints
  size_t input_points = 0;
  size_t keypoint_candidates = 0;  // boundary points before LRF filtering
};

// The whole chain. `apply_smoothing` is true for scenes and false for training scans
// (the seed smooths scenes only). Stage times go to `timings` when it is not null.
FrontEndResult extractFeatures(const Scene& scene, const FrontEndParams& params, bool apply_smoothing,
                               StageTimings* timings = nullptr, const ShouldStop& should_stop = {});

}  // namespace ism
