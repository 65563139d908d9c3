#pragma once
// What upright vote frames are made of, per described keypoint: its height above the floor, its
// surface normal turned towards the sensor, and the direction from it into its support (to the
// centroid of the surface points around it). A keypoint on an occluding contour or a boundary
// has its surface on one side only, so that direction points into the object even where the
// normal is vertical (the edge of a seat or a table top) and the SHOT frame's axes are not
// stable (a flat support leaves their signs to chance).
#include <vector>

#include "core/common/types.h"

namespace ism {

// Fills features.gravity, heights (when the floor is known), normals and support_directions.
// `described` holds each feature's index into `surface` (computeShot's output); `radius` is the
// support whose centroid is taken.
void addUprightGeometry(const Surface& surface, const std::vector<int>& described, const Gravity& gravity,
                        float radius, Features& features);

}  // namespace ism
