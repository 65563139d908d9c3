#pragma once
// Training: meshes -> virtual scans -> front end -> codebook(s) -> votes -> leave-one-out
// thresholds and box statistics -> Model. The training set comes from manifest.h; the votes
// and the thresholds have files of their own (votes.h, leave_one_out.h).
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/model/model.h"
#include "core/scanner/scanner.h"
#include "core/training/manifest.h"

namespace ism {

struct TrainingParams {
  FrontEndParams front_end;  // smoothing is stored for scenes; training scans are not smoothed
  ViewRingParams views;      // 12 views, as in the seed
  CameraIntrinsics intrinsics;
  NoiseParams noise;
  bool global_codebook = true;
  bool separated_codebooks = true;
  KMeansParams global_kmeans;                          // k = 300
  KMeansParams separated_kmeans{150, 30, 1e-4f, 60000, 42};
  ActivationParams knn{ActivationStrategy::kKnn, 1, 0.25f};
  ActivationParams cutoff{ActivationStrategy::kCutoff, 1, 0.25f};
  // Leave-one-out threshold = mean - std of the held-out scores (the seed's rule), but at least
  // this fraction of the mean: with few, dissimilar models the std can exceed the mean, and a
  // threshold <= 0 would admit every peak. In [0, 1]; 0 keeps the seed's rule unchanged.
  float threshold_floor = 0.5f;
  std::map<std::string, float> bin_sizes;  // per category; others get default_bin_size
  float default_bin_size = 0.1f;
  int threads = 0;  // 0 = all cores
  // Progress lines ("scanning couch 3/5 ...") with timings; may be empty.
  std::function<void(const std::string&)> progress;
  std::string command;  // recorded in provenance
};

// Seed bin sizes: ~10 cm for chairs, ~20 cm for tables and couches.
float defaultBinSize(const std::string& category);

// One scan's features, as used by training and by evaluation on synthetic scans.
struct TrainingScan {
  std::string category;
  int model_index;  // which mesh of the category
  Features features;
  Eigen::Vector3f object_center;  // true centre (world frame)
  OrientedBox keypoint_box;
};

// Renders and describes every mesh from every view.
std::vector<TrainingScan> scanMeshes(const std::vector<TrainingMesh>& meshes, const TrainingParams& params);

// Everything after scanning (codebooks, votes, thresholds, boxes); exposed for evaluation.
Model trainFromScans(const std::vector<TrainingScan>& scans, const std::vector<std::string>& categories,
                     const TrainingParams& params);

Model train(const std::vector<TrainingMesh>& meshes, const TrainingParams& params);

}  // namespace ism
