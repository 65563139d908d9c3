#pragma once
// Unorganized clouds seen as one view: a range image of the cloud from its sensor origin, so that
// the occluding-contour detector of depth frames (occluding_contours.h) also runs on fused room
// scans and point samples. Training scans are rendered depth frames, so scenes of every kind and
// the training scans then share one keypoint detector; the boundary test, the seed's detector for
// clouds, fires on 22-79 % of a sparse cloud's points. Borders found on range images made from
// unorganized scans are the keypoints of Steder et al., "Point feature extraction on 3D range
// scans taking into account object boundaries" (NARF), ICRA 2011; PCL's pcl::RangeImage makes
// such images with a spherical projection, as here.
#include <Eigen/Core>

#include "core/common/types.h"
#include "core/frontend/params.h"

namespace ism {

// The points of `points` nearest to `origin` in each pixel of a spherical image (azimuth around
// `up` by elevation), as an organized Scene: its cloud holds those points, pixel_index their
// pixels. The pixel's angle is params.pixel_spacings times the median angle between a point and
// its nearest neighbour, seen from the origin, so that a pixel holds about one point whatever the
// density; holes left between points are what ContourParams::max_gap looks across. Azimuth is
// counted from the points' mean direction, so a single frame sits in the middle of its image and
// a 360-degree scan has its seam behind the origin. An image of fewer than 3 x 3 pixels (fewer
// than 2 points) is returned empty: image_width = 0.
Scene rangeImageView(const XyzCloud& points, const Eigen::Vector3f& origin, const Eigen::Vector3f& up,
                     const RangeImageParams& params);

}  // namespace ism
