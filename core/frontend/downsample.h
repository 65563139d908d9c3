#pragma once
// Downsampling, the front end's first stage: the scene's points -> one centroid per occupied
// voxel of edge leaf_size.
#include "core/common/types.h"
#include "core/frontend/params.h"

namespace ism {

// Voxel-grid centroid downsampling, in pcl::VoxelGrid's output order. Non-finite points are
// skipped. Throws Error(kInvalidInput) when the leaf size is not positive or too small for the
// cloud's extent.
XyzCloud::Ptr downsample(const Cloud& cloud, const DownsampleParams& params);

}  // namespace ism
