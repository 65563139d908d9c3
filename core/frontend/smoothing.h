#pragma once
// Smoothing (scenes only; training scans skip it): Moving Least Squares moves each downsampled
// point onto a polynomial surface fitted to its neighbours.
#include "core/common/types.h"
#include "core/frontend/params.h"

namespace ism {

// Moving Least Squares smoothing (points are moved onto the fitted surface), as
// pcl::MovingLeastSquares projects them; points with fewer than 3 neighbours are dropped.
XyzCloud::Ptr smooth(const XyzCloud& cloud, const SmoothingParams& params);

}  // namespace ism
