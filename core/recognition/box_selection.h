#pragma once
// Box selection: a hypothesis' supporting keypoints get a PCA box, and a hypothesis whose box is
// outside the size limits learned from the training scans (BoxStats) is rejected.
#include <vector>

#include "core/common/types.h"
#include "core/model/model.h"

namespace ism {

// PCA oriented box of points.
OrientedBox fitOrientedBox(const std::vector<Eigen::Vector3f>& points);

// The box's volume is within [min_volume, max_volume] and its longest edge at most max_edge.
bool passesBoxSelection(const OrientedBox& box, const BoxStats& stats);

}  // namespace ism
