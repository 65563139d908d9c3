#pragma once
// The front end: cloud -> downsampled points -> keypoints and normals -> SHOT descriptors with
// LRFs. An organized scene's keypoints (occluding contours of the pixel grid) come first and
// normals only around them; an unorganized cloud's (boundary points) need every normal first.
// Each stage is a free function (or NormalEstimator) with typed input, output and parameter
// struct, testable alone; extractFeatures() chains them.
#include <memory>
#include <vector>

#include "core/common/types.h"
#include "core/frontend/params.h"

namespace ism {

using XyzCloud = pcl::PointCloud<pcl::PointXYZ>;
class NeighbourGrid;

// Voxel-grid centroid downsampling.
XyzCloud::Ptr downsample(const Cloud& cloud, const DownsampleParams& params);

// Moving Least Squares smoothing (points are moved onto the fitted surface).
XyzCloud::Ptr smooth(const XyzCloud& cloud, const SmoothingParams& params);

// PCA normals over params.radius, flipped towards `viewpoint`, computed for the points asked
// for. SHOT reads the normals of the points within its radius of a keypoint only: on the Kinect
// frames that is 9-28% of the points, so an organized scene, whose keypoints are known before its
// normals, computes no others. A normal is undefined (and its point not part of the surface) with
// fewer than 3 neighbours. `cloud` must outlive the estimator.
class NormalEstimator {
 public:
  NormalEstimator(const XyzCloud& cloud, const NormalParams& params, const Eigen::Vector3f& viewpoint);
  ~NormalEstimator();

  void computeAll();
  // The normals of the points with wanted[i] != 0 (one flag per cloud point) not computed yet.
  void compute(const std::vector<uint8_t>& wanted);
  // The normals of every point within `radius` of one of cloud[centres].
  void computeNear(const std::vector<int>& centres, float radius);

  const XyzCloud& cloud() const { return cloud_; }
  // defined()[i]: point i's normal has been computed and is defined.
  const std::vector<uint8_t>& defined() const { return defined_; }
  // The nearest point with a defined normal within `max_distance` of `query`, or -1; only points
  // whose normals have been computed count.
  int nearestDefined(const Eigen::Vector3f& query, float max_distance) const;
  // The flags of the points within `radius` of one of `queries`.
  std::vector<uint8_t> pointsNear(const std::vector<Eigen::Vector3f>& queries, float radius) const;
  // The points with a defined normal, in cloud order. index_in_surface (when not null) receives,
  // per cloud point, its index in the surface or -1.
  Surface::Ptr surface(std::vector<int>* index_in_surface = nullptr) const;

 private:
  const XyzCloud& cloud_;
  NormalParams params_;
  Eigen::Vector3f viewpoint_;
  std::unique_ptr<NeighbourGrid> grid_;  // cells of the normals' radius
  std::vector<pcl::PointNormal> normals_;
  std::vector<uint8_t> computed_, defined_;
};

// Every point's normal (NormalEstimator::computeAll): the surface of the boundary test.
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
template <class PointT>
std::vector<int> thinKeypoints(const pcl::PointCloud<PointT>& points, const std::vector<int>& keypoints, float spacing);

// Occluding-contour keypoints before any normal: indices into normals.cloud() (ascending) of
// what nearestSurfacePoints picks for the contour pixels at max_distance = leaf_size, thinned to
// params.min_spacing. Computes the normals of the points within leaf_size of a contour pixel
// (a keypoint must have one). Throws ism::Error when the scene is not organized.
std::vector<int> detectContourKeypoints(const Scene& scene, NormalEstimator& normals, const KeypointParams& params,
                                        float leaf_size);

// Indices into `surface` (the downsampled `scene`) of keypoints by params.method, thinned to
// params.min_spacing. `leaf_size` is the downsampling voxel the surface was made with.
std::vector<int> detectKeypoints(const Scene& scene, const Surface& surface, const KeypointParams& params,
                                 float leaf_size);

// SHOT (352-d, unit length) and its LRF at each keypoint, the whole surface as support.
// Keypoints with an undefined LRF or descriptor (too few neighbours, NaN) are dropped.
Features describe(const Surface& surface, const std::vector<int>& keypoints, const ShotParams& params);

struct FrontEndResult {
  // Downsampled (and smoothed) points with normals: all of them for the boundary test, those
  // near the keypoints (what SHOT reads) on organized scenes.
  Surface::Ptr surface;
  Features features;  // described keypoints
  size_t input_points = 0;
  size_t surface_points = 0;  // downsampled (and smoothed) points, the surface keypoints are described on
  size_t keypoint_candidates = 0;  // detected keypoints before LRF filtering
};

// The whole chain. `apply_smoothing` is true for scenes and false for training scans
// (the seed smooths scenes only). Stage times go to `timings` when it is not null.
FrontEndResult extractFeatures(const Scene& scene, const FrontEndParams& params, bool apply_smoothing,
                               StageTimings* timings = nullptr, const ShouldStop& should_stop = {});

}  // namespace ism
