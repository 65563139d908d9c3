#include "core/frontend/downsample.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/common/error.h"
#include "core/common/hash.h"
#include "core/common/radix_sort.h"
#include "core/frontend/param_checks.h"

namespace ism {
namespace {

// Voxel centroids in pcl::VoxelGrid's output order (ascending linear voxel index: z, then y,
// then x). Written here rather than with pcl::VoxelGrid, which numbers voxels with a 32-bit index
// (silently returning its input when a room at a fine leaf overflows it) and sorts with std::sort;
// a 64-bit index does not overflow, and a radix sort of the 64-bit keys is the cheaper sort.
// Non-finite points are skipped, as VoxelGrid does.
void voxelCentroids(const Cloud& cloud, float leaf, XyzCloud& out) {
  const float inverse_leaf = 1.0f / leaf;
  Eigen::Array3f lo = Eigen::Array3f::Constant(std::numeric_limits<float>::max());
  Eigen::Array3f hi = Eigen::Array3f::Constant(std::numeric_limits<float>::lowest());
  for (const auto& p : cloud) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    lo = lo.min(p.getArray3fMap());
    hi = hi.max(p.getArray3fMap());
  }
  if (!(lo <= hi).all()) return;  // no finite point
  Eigen::Array<int64_t, 3, 1> first, count;
  for (int axis = 0; axis < 3; ++axis) {
    const double low = std::floor(lo[axis] * inverse_leaf);  // in float, as each point is assigned below
    const double high = std::floor(hi[axis] * inverse_leaf);
    // Voxel numbers beyond this are no longer exact in the float arithmetic that assigns points.
    constexpr double kMaxVoxelCoordinate = std::numeric_limits<int>::max() / 2.0;
    if (std::abs(low) > kMaxVoxelCoordinate || std::abs(high) > kMaxVoxelCoordinate) {
      throw Error(ErrorCode::kInvalidInput,
                  "downsample.leaf_size = " + std::to_string(leaf) + " is too small for coordinates up to " +
                      std::to_string(std::max(std::abs(lo[axis]), std::abs(hi[axis]))) + " m");
    }
    first[axis] = static_cast<int64_t>(low);
    count[axis] = static_cast<int64_t>(high) - first[axis] + 1;
  }
  if (static_cast<double>(count[0]) * static_cast<double>(count[1]) * static_cast<double>(count[2]) >= 0x1p63) {
    throw Error(ErrorCode::kInvalidInput, "downsample.leaf_size = " + std::to_string(leaf) +
                                              " divides the cloud's extent into more than 2^63 voxels");
  }
  // Each point summed into its voxel's entry of an open-addressing table, in the points' order,
  // then the voxels (a Kinect frame's 250,000 points fill some 16,000) sorted by index: cheaper
  // than sorting the points, and the same sums in the same order.
  struct Voxel {
    uint64_t index;
    Eigen::Vector3d sum;
    uint32_t count;
  };
  std::vector<Voxel> voxels;
  constexpr uint32_t kEmpty = std::numeric_limits<uint32_t>::max();
  std::vector<uint32_t> slots;  // into voxels; a power of two of them, at most half full
  const auto rehash = [&](size_t size) {
    slots.assign(size, kEmpty);
    for (size_t v = 0; v < voxels.size(); ++v) {
      size_t slot = mix64(voxels[v].index) & (size - 1);
      while (slots[slot] != kEmpty) slot = (slot + 1) & (size - 1);
      slots[slot] = static_cast<uint32_t>(v);
    }
  };
  size_t initial = 1024;
  while (initial < cloud.size() / 8) initial *= 2;
  rehash(initial);
  for (const auto& p : cloud) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    const auto voxel = [&](float v, int axis) {
      return std::clamp<int64_t>(static_cast<int64_t>(std::floor(v * inverse_leaf)) - first[axis], 0, count[axis] - 1);
    };
    const uint64_t index = static_cast<uint64_t>((voxel(p.z, 2) * count[1] + voxel(p.y, 1)) * count[0] + voxel(p.x, 0));
    const size_t mask = slots.size() - 1;
    size_t slot = mix64(index) & mask;
    while (slots[slot] != kEmpty && voxels[slots[slot]].index != index) slot = (slot + 1) & mask;
    if (slots[slot] == kEmpty) {
      slots[slot] = static_cast<uint32_t>(voxels.size());
      voxels.push_back({index, Eigen::Vector3d::Zero(), 0});
      if (2 * voxels.size() > slots.size()) {
        rehash(2 * slots.size());
        slot = mix64(index) & (slots.size() - 1);
        while (voxels[slots[slot]].index != index) slot = (slot + 1) & (slots.size() - 1);
      }
    }
    Voxel& v = voxels[slots[slot]];
    v.sum += p.getVector3fMap().cast<double>();
    ++v.count;
  }
  std::vector<std::pair<uint64_t, int>> keyed(voxels.size());
  for (size_t v = 0; v < voxels.size(); ++v) keyed[v] = {voxels[v].index, static_cast<int>(v)};
  sortByKey(keyed);
  out.reserve(out.size() + keyed.size());
  for (const auto& [index, v] : keyed) {
    const Voxel& voxel = voxels[static_cast<size_t>(v)];
    const Eigen::Vector3f centroid = (voxel.sum / static_cast<double>(voxel.count)).cast<float>();
    out.push_back(pcl::PointXYZ(centroid.x(), centroid.y(), centroid.z()));
  }
}

}  // namespace

XyzCloud::Ptr downsample(const Cloud& cloud, const DownsampleParams& params) {
  requirePositive(params.leaf_size, "downsample.leaf_size");
  XyzCloud::Ptr out(new XyzCloud);
  if (cloud.empty()) return out;
  voxelCentroids(cloud, params.leaf_size, *out);
  out->width = static_cast<uint32_t>(out->size());
  out->height = 1;
  out->is_dense = true;
  return out;
}

}  // namespace ism
