#pragma once
// SHOT (Tombari, Salti, Di Stefano, ECCV 2010: the 352-d shape histogram) with its local
// reference frame, as PCL 1.13's SHOTLocalReferenceFrameEstimation and SHOTEstimation compute
// them (features/impl/shot_lrf.hpp, shot.hpp) over the same support in the same order: on the
// frames measured, bit for bit (tests/core/shot_test.cc).
//
// Why not PCL's estimators: they search each support three times (PCL's OpenMP LRF searches
// twice, SHOT once more), allocate per keypoint, and call glibc's acos and atan2 and branch
// unpredictably per support point. Here one search feeds the frame and the histogram, the
// angles come from a rational arctangent within a few ulp of glibc's, and the per-point
// arithmetic vectorises.
#include <vector>

#include "core/common/types.h"
#include "core/frontend/params.h"

namespace ism {

constexpr int kShotLength = 352;

// SHOT and its LRF (rows x, y, z) at each of `keypoints` (indices into `surface`), in their
// order, with the whole surface within params.radius as support. A keypoint is dropped when its
// support, itself included, has fewer than params.min_neighbours points, when its LRF is
// undefined (fewer than 5 support points apart from the keypoint, or not finite) or when no
// support point votes (a zero or non-finite histogram). When `described` is not null it receives
// the keypoint of each feature. Results do not depend on the number of OpenMP threads.
// Throws ism::Error (kInvalidInput) when a keypoint is outside the surface or the radius is not
// positive and finite.
Features computeShot(const Surface& surface, const std::vector<int>& keypoints, const ShotParams& params,
                     std::vector<int>* described = nullptr);

}  // namespace ism
