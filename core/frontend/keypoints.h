#pragma once
// Keypoints: where the scene is described. Organized scenes (depth images, organized clouds) take
// the points on occluding contours (occluding_contours.h), found before any normal; unorganized
// clouds take boundary points (largest angular gap among the neighbours), which need every
// normal first. Either set can be thinned to one keypoint per cube of min_spacing. Keypoints
// sampled on the surface (sampleSurfaceKeypoints) can join either.
#include <cstdint>
#include <vector>

#include "core/common/types.h"
#include "core/frontend/normals.h"
#include "core/frontend/params.h"

namespace ism {

// Indices into `surface` of boundary points (largest angular gap > threshold).
std::vector<int> detectBoundaryKeypoints(const Surface& surface, const KeypointParams& params);

// params.method with kAuto resolved for `scene`: occluding contours when it is organized, else
// params.unorganized (the range image's contours or the boundary test).
KeypointMethod resolveKeypointMethod(const KeypointParams& params, const Scene& scene);

// Indices into `surface` (ascending, unique) of the surface point nearest to each of
// cloud[point_indices], when it is within `max_distance`. With max_distance = the leaf size this
// picks the voxel each point fell into, also after smoothing has moved the voxel centroids
// (a flat face lying on a voxel boundary ends up on either side of it).
std::vector<int> nearestSurfacePoints(const Surface& surface, const Cloud& cloud, const std::vector<int>& point_indices,
                                      float max_distance);

// The first of `keypoints` (in order) in each cube of edge `spacing`; spacing 0 keeps them all.
template <class PointT>
std::vector<int> thinKeypoints(const pcl::PointCloud<PointT>& points, const std::vector<int>& keypoints, float spacing);

// Keypoints on surfaces, not only on their contours: of the points with eligible[i] != 0, the one
// nearest the centre of each cube of edge `spacing` that holds at least `min_points` of them,
// unless a point that is not eligible lies within `clearance` of it (ascending indices into
// `points`).
struct SurfaceSampling {
  float spacing = 0;
  int min_points = 1;
  float clearance = 0;
};
std::vector<int> sampleSurfaceKeypoints(const XyzCloud& points, const std::vector<uint8_t>& eligible,
                                        const SurfaceSampling& sampling);

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

}  // namespace ism
