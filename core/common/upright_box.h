#pragma once
// Boxes that stand upright in a gravity frame (z up): how furniture is boxed by the datasets
// that measure 3D detection (SUN RGB-D, ScanNet) and by the recognizer's default answers. Their
// overlap is the footprints' polygon intersection times the overlap of the height ranges.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/common/types.h"

namespace ism {

struct UprightBox {
  Eigen::Vector3f center = Eigen::Vector3f::Zero();  // gravity frame
  Eigen::Vector3f size = Eigen::Vector3f::Zero();    // along the box's own x, y and up
  float yaw = 0;  // rotation of the box's x axis about up, from the gravity frame's x (rad)

  float volume() const { return size.x() * size.y() * size.z(); }
  // Scene coordinates, given the rotation the gravity frame was made with (scene -> gravity).
  OrientedBox toScene(const Eigen::Matrix3f& to_gravity) const;
};

// The upright box around `box` (scene coordinates) in the gravity frame of `to_gravity`. Its yaw
// is that of whichever of the box's axes is most horizontal, and its extents are those of the
// box's corners along that yaw and up: exact for a box that already stands upright, the tightest
// such box otherwise.
UprightBox uprightBoxOf(const OrientedBox& box, const Eigen::Matrix3f& to_gravity);

// Whether `p` (gravity frame) lies over the box's footprint, at any height.
bool insideFootprint(const Eigen::Vector3f& p, const UprightBox& box);

// The area the two footprints share (m^2), at any heights.
float footprintOverlap(const UprightBox& a, const UprightBox& b);

// Intersection over union of the two boxes' volumes; 0 when either is empty.
float intersectionOverUnion(const UprightBox& a, const UprightBox& b);

}  // namespace ism
