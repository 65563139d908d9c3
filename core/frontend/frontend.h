#pragma once
// The front end: cloud -> downsampled points -> keypoints and normals -> SHOT descriptors with
// LRFs. An organized scene's keypoints (occluding contours of the pixel grid) come first and
// normals only around them; an unorganized cloud's (boundary points) need every normal first.
// Each stage has its own file, a free function (or NormalEstimator) with typed input, output
// and parameter struct (params.h), testable alone:
//   downsample.h          voxel-grid centroids
//   smoothing.h           Moving Least Squares (scenes only)
//   normals.h             PCA normals towards the sensor
//   keypoints.h           which detector, boundary points, thinning
//   occluding_contours.h  the detector of organized scenes
//   shot.h                SHOT descriptors and their LRFs
// extractFeatures() chains them.
#include <vector>

#include "core/common/types.h"
#include "core/frontend/downsample.h"
#include "core/frontend/keypoints.h"
#include "core/frontend/normals.h"
#include "core/frontend/occluding_contours.h"
#include "core/frontend/params.h"
#include "core/frontend/smoothing.h"

namespace ism {

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
