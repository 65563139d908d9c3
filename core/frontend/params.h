#pragma once
// Parameters of the front end shared by training and recognition. All of them are stored in
// the model file, so recognition always runs the front end the model was trained with.
// Defaults are the seed's values (../shared/docs/ALGORITHM.md, "Recognition" 1-5).
#include <cmath>

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

struct KeypointParams {
  float radius = 0.03f;                        // neighbourhood of the boundary test (m)
  float angle_threshold = static_cast<float>(M_PI / 2);  // largest angular gap that is still "inside"
};

struct ShotParams {
  float radius = 0.08f;   // support radius (m)
  // A keypoint whose support has fewer points has no stable LRF and is dropped.
  int min_neighbours = 10;
};

struct FrontEndParams {
  DownsampleParams downsample;
  SmoothingParams smoothing;
  NormalParams normals;
  KeypointParams keypoints;
  ShotParams shot;
};

}  // namespace ism
