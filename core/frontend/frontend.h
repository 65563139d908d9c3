#pragma once
// The front end: cloud -> downsampled surface with normals -> keypoints (occluding contours of
// the pixel grid, or boundary points for unorganized clouds) ->
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

// kAuto resolved for `scene`: occluding contours when it is organized, else the boundary test.
KeypointMethod resolveKeypointMethod(KeypointMethod method, const Scene& scene);

// Indices into scene.cloud of the pixels on occluding contours (see ContourParams): the near
// side of depth jumps and silhouettes against no return, never the image border or a shadow.
// Throws ism::Error when the scene is not organized.
std::vector<int> detectOccludingContourPixels(const Scene& scene, const ContourParams& params);

// Indices into `surface` (ascending, unique) of the surface point nearest to each of
// cloud[point_indices], when it is within `max_distance`. With max_distance = the leaf size this
// picks the voxel each point fell into, also after smoothing has moved the voxel centroids
// (a flat face lying on a voxel boundary ends up on either side of it).
std::vector<int> nearestSurfacePoints(const Surface& surface, const Cloud& cloud, const std::vector<int>& point_indices,
                                      float max_distance);

// The first of `keypoints` (in order) in each cube of edge `spacing`; spacing 0 keeps them all.
std::vector<int> thinKeypoints(const Surface& surface, const std::vector<int>& keypoints, float spacing);

// Indices into `surface` (the downsampled `scene`) of keypoints by params.method, thinned to
// params.min_spacing. `leaf_size` is the downsampling voxel the surface was made with.
std::vector<int> detectKeypoints(const Scene& scene, const Surface& surface, const KeypointParams& params,
                                 float leaf_size);

// SHOT (352-d, unit length) and its LRF at each keypoint, the whole surface as support.
// Keypoints with an undefined LRF or descriptor (too few neighbours, NaN) are dropped.
Features describe(const Surface& surface, const std::vector<int>& keypoints, const ShotParams& params);

struct FrontEndResult {
  Surface::Ptr surface;  // downsampled (and smoothed) points with normals
  Features features;     // described keypoints
  size_t input_points = 0;
  size_t keypoint_candidates = 0;  // detected keypoints before LRF filtering
};

// The whole chain. `apply_smoothing` is true for scenes and false for training scans
// (the seed smooths scenes only). Stage times go to `timings` when it is not null.
FrontEndResult extractFeatures(const Scene& scene, const FrontEndParams& params, bool apply_smoothing,
                               StageTimings* timings = nullptr, const ShouldStop& should_stop = {});

}  // namespace ism
