#pragma once
// Occluding contours: the keypoint detector of organized scenes. On the range image (distance
// to the sensor per pixel) a pixel is an edge where a neighbour lies farther by more than the
// jump (ContourParams): the near side of a depth discontinuity or a silhouette against no return.
// Shadows (the far side) and the image border never are.
#include <vector>

#include "core/common/types.h"
#include "core/frontend/params.h"

namespace ism {

// Indices into scene.cloud of the pixels on occluding contours (see ContourParams): the near
// side of depth jumps and silhouettes against no return, never the image border or a shadow.
// Throws ism::Error when the scene is not organized.
std::vector<int> detectOccludingContourPixels(const Scene& scene, const ContourParams& params);

}  // namespace ism
