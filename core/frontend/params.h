#pragma once
// Parameters of the front end shared by training and recognition. All of them are stored in
// the model file, so recognition always runs the front end the model was trained with.
// Defaults are the seed's values (the 2012 thesis this project implements: its recognition steps,
// downsampling to SHOT), except the keypoint detector on organized scenes: occluding contours
// instead of boundary points.
#include <cmath>

#include "core/gravity/gravity.h"

namespace ism {

struct DownsampleParams {
  float leaf_size = 0.01f;  // voxel edge (m); each occupied voxel becomes its centroid
};

struct SmoothingParams {
  bool enabled = true;     // scenes only; training scans skip it (TrainingParams decides)
  float radius = 0.02f;    // MLS search radius (m)
  int polynomial_order = 2;
};

struct NormalParams {
  float radius = 0.03f;  // PCA neighbourhood (m); normals are flipped towards the sensor
};

enum class KeypointMethod {
  kAuto,              // organized scene -> occluding contours, unorganized -> boundary test
  kBoundary,          // the seed's detector: largest angular gap of the neighbours > angle_threshold
  kOccludingContour,  // depth discontinuities of the pixel grid; needs an organized scene
  kRangeImage,        // occluding contours of the range image seen from the sensor (range_image.h)
};

// Occluding contours: a pixel is an edge when, within `window` pixels along one of the 8
// directions, the range (distance to the sensor) jumps by more than
// max(min_jump, relative_jump * range). A FARTHER neighbour makes it an occluding edge (a keypoint
// candidate), a NEARER one the shadow of something in front (never a keypoint). The threshold
// has to clear the Kinect's disparity quantisation (z^2 / 315 m: 2.9 cm at 3 m) plus noise
// between two pixels (4 sqrt(2) sigma(z), sigma = 0.0012 + 0.0019 (z - 0.4)^2: 8 cm at 3 m),
// together 0.036 z at 3 m, 0.049 z at 4 m, 0.063 z at 5 m; a floor seen from 1.2 m up adds
// its slope over 2 px, 2 z / (525 * 1.2 m) = 0.013 z at 4 m. 0.07 keeps walls quiet to ~5 m
// and floors to ~4.5 m, and still separates a chair from a wall 25 cm behind it at 3.5 m.
// Below 0.7 m the 5 cm minimum ignores steps within one object (a drawer front).
struct ContourParams {
  int window = 2;              // pixels compared in each direction; 2 spans a one-pixel mixed edge
  float min_jump = 0.05f;      // (m)
  float relative_jump = 0.07f; // fraction of the pixel's range
  // A run of pixels with no return (the projector's shadow, a specular hole) is looked across
  // for up to this many pixels: what lies behind it decides as above; a similar range means a
  // hole in one surface (no edge); nothing means a silhouette against empty space (an edge).
  // The Kinect's shadow is f * b * (1/z_near - 1/z_far) <= 39 px / z_near wide.
  int max_gap = 40;
};

// The range image an unorganized cloud is seen as (range_image.h). 2.5 spacings: at the median
// nearest-neighbour distance d of points scattered at random, a pixel of side 2.5 d holds about
// (2.5 d)^2 / (0.47^2 / density) ~ 1.4 points on average, so few pixels of a surface are holes.
struct RangeImageParams {
  float pixel_spacings = 2.5f;
  long max_pixels = 4'000'000;  // beyond it the pixels grow
};

struct KeypointParams {
  KeypointMethod method = KeypointMethod::kAuto;
  // What kAuto takes for unorganized clouds: kRangeImage, or kBoundary (the seed's). Training
  // scans are depth frames, so kRangeImage gives scenes of every kind the training's detector.
  KeypointMethod unorganized = KeypointMethod::kRangeImage;
  RangeImageParams range_image;
  float radius = 0.03f;                        // neighbourhood of the boundary test (m)
  float angle_threshold = static_cast<float>(M_PI / 2);  // largest angular gap that is still "inside"
  ContourParams contour;
  // At most one keypoint per cube of this edge (m); 0 keeps every detected point. Off by
  // default: contours are already sparse (3,376 keypoints on tum_desk), and thinning them when
  // recognising loses the support that chairs, thin as they are, need on real Kinect frames.
  float min_spacing = 0.0f;
  // Besides the contours, keypoints on the surface itself: of the points off the floor and walls,
  // the one nearest the centre of each cube of this edge (m), as PCL's ISM (Knopp et al. 2010) and
  // Seib et al.'s PointCloudDonkey describe the points of a voxel grid. 0 = contours only (the seed).
  float surface_spacing = 0.0f;
};

struct ShotParams {
  float radius = 0.08f;   // support radius (m)
  // A keypoint whose support has fewer points has no stable LRF and is dropped.
  int min_neighbours = 10;
};

struct FrontEndParams {
  DownsampleParams downsample;
  SmoothingParams smoothing;
  GravityParams gravity;
  NormalParams normals;
  KeypointParams keypoints;
  ShotParams shot;
};

}  // namespace ism
