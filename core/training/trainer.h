#pragma once
// Training: meshes -> virtual scans -> front end -> codebook(s) -> votes -> leave-one-out
// thresholds and box statistics -> Model. The training set comes from manifest.h; the votes
// and the thresholds have files of their own (votes.h, leave_one_out.h).
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/model/model.h"
#include "core/recognition/hough_space.h"
#include "core/recognition/recognizer.h"
#include "core/recognition/scene_checks.h"
#include "core/recognition/verification.h"
#include "core/scanner/scanner.h"
#include "core/training/manifest.h"

namespace ism {

struct CalibrationSample;  // calibration.h

// Codeword weights learned from the calibration rooms' peaks (discriminative_weights.h).
// Optional (ism-train --learned-weights): over five pairs of draws of the shipped recipe, chairs'
// r at 0.3 rose from 31.1 to 35.9 % and their AP@0.25 from 59.2 to 61.3, while tables' AP fell
// from 34.3 to 32.3 on every pair and the mAP from 39.1 to 38.3 (docs/EVALUATION.md, "Codeword
// weights learned from the calibration rooms' peaks").
struct DiscriminativeWeightParams {
  bool enabled = false;
  // The ridge on the codewords' slopes (per peak summed over the log-loss), chosen per category by
  // the log-loss on each calibration fold's rooms of the fit on the other folds'.
  std::vector<double> ridges = {0.003, 0.01, 0.03, 0.1, 0.3, 3.0};
  // No codeword keeps less than this share of its votes (exp(-3)).
  double lowest = 0.0498;
};

// The rendered rooms calibration (calibration.h) fits confidences to.
struct CalibrationParams {
  bool enabled = true;
  int folds = 3;              // training objects split k-fold; each fold's rooms hold its objects
  int rooms_per_fold = 40;
  int max_objects = 3;        // furniture per room (1..max)
  // The share of rooms that show a table with chairs or a couch pulled up to it (1..max_grouped
  // of them, half under its top or just clear of it), as dining sets and desks stand in real
  // rooms, where a chair at a table is partly hidden by it. Optional (ism-train --grouped-rooms):
  // with half the rooms grouped, four draws lost 1.0 point of the dev clouds' mAP on average and
  // real tables came out over-confident (docs/EVALUATION.md, "Furniture grouped at a table").
  float grouped_rooms = 0.0f;
  int max_grouped = 4;
  int clutter_boxes = 3;      // boxes, cabinets and shelves per room (0..max)
  int background_objects = 2; // background meshes (background.h) per room (0..max), where training has them
  float camera_height_min = 0.6f, camera_height_max = 1.8f;  // a robot's to a person's
  float distance_min = 1.5f, distance_max = 4.0f;             // camera to the room's middle (m)
  // Each room is also seen as an unorganized point sample, a random fraction of the frame's points
  // (log-uniform in [min, max]), and fitted apart (CategoryModel::cloud_calibration): SUN RGB-D's
  // 50,000 points of a 640x480 frame are 16 %, a 50,000-point sample of a ScanNet room leaves
  // 4-6 % of a frame's worth.
  bool clouds = true;
  float cloud_fraction_min = 0.04f, cloud_fraction_max = 0.2f;
  // Whether each room is also seen as a map (calibrationMap: one view fused per map_spacing cube,
  // 30,000-80,000 points, no pose, as a room scan is sent), its peaks added to the point samples'
  // for cloud_calibration. Recognition verifies a map in 3D from a made-up viewpoint, where a
  // shape's unseen side counts against it, so a map's peaks fit and score unlike a posed sample's.
  // Optional (ism-train --calibration-maps): on the dev clouds the ranking gains (mAP +3 to +5
  // over two ensembles, sofas most) while chairs answer less often at 0.5 (docs/EVALUATION.md,
  // "Rendered maps in the clouds' calibration").
  bool maps = false;
  int map_views = 1;
  float map_spacing = 0.015f;
  int map_points_min = 30000, map_points_max = 80000;
  // Peaks are collected down to this fraction of each category's leave-one-out threshold.
  float lowest_score_fraction = 0.02f;
  // Whether the confidence of categories that are not flat-topped (top_extent.h) weighs the
  // verification's shape profile distance (verification.h, ShapeProfile) besides the fit; false
  // fits it without (ism-train --no-shape-profile).
  bool shape_profile = true;
  // Where the rooms' peaks are centred (hough_space.h): as recognition's default centres them, so
  // that the confidence is learned on the peaks recognition finds; recognition is to use the same
  // (ism-train, ism-detect and ism-eval --bin-peaks: kBin).
  PeakCentre peak_centre = RecognitionOptions{}.peak_centre;
  // The terms of verification's fit the rooms' peaks are verified with (ism-train --fit-terms):
  // recognition's default ones; recognition is to use the same.
  FitTerms fit_terms = RecognitionOptions{}.verification.fit_terms;
  // Whether the rooms' verified peaks go through recognition's checks of the scene around them
  // (scene_checks.h) before they are labelled, so that the confidence is the chance that a peak
  // which passed them is right, as the ones recognition answers have; false labels every verified
  // peak (ism-train --no-calibration-scene-checks).
  bool scene_checks = true;
  // Whether a peak on an object of another category of its kind (categoryKind: a dining chair's
  // peak on an office chair) is left out of its category's fit rather than counted against it
  // (ism-train --calibration-kind-negatives counts it). The rendered rooms label such a peak
  // false, while a robot, the real scans' ground truth (chair, table, sofa) and the evaluation
  // take it as the chair it is, and the other category's peak there competes with it
  // (suppression.h). Over four draws on the dev scans chair r at 0.5 rose from 13.6 to 16.6 %
  // (no draw lower), chairs' AP fell from 53.8 to 52.7 (docs/EVALUATION.md, "Chairs of the other
  // kind in the calibration").
  bool kinds = true;
  // Those checks: all of recognition's but the seat's area (seat_area.h), the surface running on
  // beside a couch or behind a chair's back, the side facing the sensor, the top of the body's
  // clearance from a wall, a backrest seen through (open_top.h, under_top.h, top_seen.h; measured
  // in recognition only) and a table's top grown across what the sensor cannot see
  // (top_extent.h). Over four draws the seat's area in recognition alone moved the clouds' mAP by
  // +0.2 to +0.8, and in the calibration too by -0.8 to +0.9 (docs/EVALUATION.md, "A seat's
  // area"); on three pairs of draws the run-on in the calibration too cost the clouds 0.4 to 2.2
  // points against recognition alone ("A bed's mattress beside a couch"), and the hidden top 0.0
  // to 0.2 ("A table's top behind a chair").
  SceneCheckParams checks = [] {
    SceneCheckParams p;
    p.seat_area.enabled = false;
    p.open_top.max_run_on = 0;
    p.open_top.near_edge = 0;
    p.open_top.upper_clearance = 0;
    p.top_seen.enabled = false;
    p.under_top.near_edge = 0;
    p.top_extent.max_hidden_run = 0;
    return p;
  }();
  // Each category's slopes drawn towards the slopes all categories share (fitCalibrations), for
  // categories with few training meshes: with 20-60 positive peaks per category the slopes of one
  // category alone change sign from draw to draw. The spread is chosen among these by leaving one
  // fold's rooms out (0 fits each alone). Optional (ism-train --calibration-pooling): over eight
  // draws of the shipped recipe the dev clouds moved -0.8 to +1.5 (docs/EVALUATION.md,
  // "Categories' slopes pooled").
  bool pooled = false;
  std::vector<double> pooling_spreads = {0.0, 0.25, 0.5, 1.0, 2.0};
  // Codeword weights learned from the rooms' peaks before the confidence is fitted, on rooms of
  // another draw.
  DiscriminativeWeightParams learned_weights;
  uint32_t seed = 7;
};

// The project's front end, coarser than the seed's (1 cm voxels, 3 cm normals, 8 cm SHOT): the
// clouds robots send are often sparser than a Kinect frame (a 50,000-point sample of a fused room
// has its points 1.4-3.3 cm apart, a SHOT of 8 cm holds 8-36 of them), so descriptors are made
// at a resolution every input reaches: voxels of kDefaultLeafSize, normals over 2.5 and SHOT over 6
// of them (the ratios of the seed's radii to a finer leaf would starve the normals). Furniture's
// parts span decimetres, so little is lost on Kinect frames. The scales were chosen on the
// development scans in docs/EVALUATION.md's ablation (2, 2.5, 3, 3.5, 4 cm leaves).
inline constexpr float kDefaultLeafSize = 0.03f;
FrontEndParams defaultFrontEnd();

struct TrainingParams {
  // defaultFrontEnd(); smoothing is stored for scenes; training scans are not smoothed
  FrontEndParams front_end = defaultFrontEnd();
  // Upright votes with the height test: see VotingParams. The seed's: LRF votes, no heights.
  VotingParams voting{VoteFrame::kUpright, 0.1f, true};
  // Scans see the mesh standing on a floor, as a robot sees furniture: its legs end on the floor
  // rather than against empty space, and the floor (never a keypoint) is in its descriptors'
  // support. The seed rendered the mesh alone.
  bool render_floor = true;
  float floor_size = 8.0f;  // m, square
  // Meshes without a size (manifest rows without one, --folders; MeshPlacement::uniform) scaled by
  // their height alone, as the seed's preset does. false: by the best fit of their box to the
  // category's typical width, depth and height. A PSB couch scaled to a couch's height came out
  // 1.5 to 3.5 m long; docs/EVALUATION.md (the seed's baseline) measures both.
  bool unsized_by_height = false;
  // Points kept per training mesh for verification (TrainingObject::surface): about this far
  // apart (m), at most shape_points of them. 0 keeps none, and recognition then verifies nothing
  // (ism-train --no-verification): docs/EVALUATION.md measures both.
  float shape_spacing = 0.02f;
  int shape_points = 1500;
  CalibrationParams calibration;  // the seed's models have none
  // 12 views, as in the seed, but from 3.5 m or farther rather than as near as the object fits
  // in view (1.6 m for a chair): robots see furniture from across a room, where a Kinect's
  // points are sparser and noisier and its shadows wider. docs/EVALUATION.md measures it.
  ViewRingParams views{12, 20.0f, 0.0f, 3.5f};
  // Besides its views, each mesh's views fused into one map, as a robot's mapping stack or a
  // ScanNet reconstruction shows furniture: surface all around, the views' points averaged per
  // `spacing` cube as a TSDF averages their noise, no image grid, its contours seen from view 0's
  // camera as recognition looks at a map from a made-up viewpoint (viewpoint.h). Its features vote
  // as a view's do. Optional (ism-train --fused-scans): on the dev clouds it lowered the mAP
  // (docs/EVALUATION.md, "Fused training scans").
  struct FusedScanParams {
    bool enabled = false;
    float spacing = 0.015f;  // m
    float margin = 0.5f;     // floor kept around the object's footprint (m)
  } fused;
  CameraIntrinsics intrinsics;
  NoiseParams noise;
  bool global_codebook = true;
  bool separated_codebooks = true;
  KMeansParams global_kmeans;                          // k = 300
  // The global codebook's k-means on as many descriptors of each category (balancedRows) instead
  // of a sample of them pooled (the seed's), so that a category trained from more meshes takes no
  // codewords from the others. Three draws of the shipped meshes gained 1.6 and 1.8 points of the
  // dev clouds' mAP with it (docs/EVALUATION.md, "A codebook balanced over the categories").
  bool balanced_global_codebook = true;
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
  // Given the calibration's labelled peaks and the model with the curves fitted to them
  // (ism-train --calibration-samples, which tests/eval/domain_gap.py sets beside the real scans'
  // candidates); may be empty.
  std::function<void(const Model&, const std::vector<CalibrationSample>&)> calibration_samples;
  std::string command;  // recorded in provenance
};

// Training as the seed (the 2012 thesis) describes it: no gravity stage, votes in
// the SHOT LRF, meshes rendered alone. The defaults of TrainingParams are the project's own.
TrainingParams seedTrainingParams();

// Another draw of training's randomness (k-means starts, sensor noise, calibration rooms): each
// stream's seed a function of `seed` (ism-train --seed, ism-eval baseline --seed).
void reseed(TrainingParams& params, uint32_t seed);

// Seed bin sizes: ~10 cm for chairs, ~20 cm for tables and couches.
float defaultBinSize(const std::string& category);

// One scan's features, as used by training and by evaluation on synthetic scans.
struct TrainingScan {
  std::string category;
  int model_index;  // which mesh of the category
  Features features;
  Eigen::Vector3f object_center;  // true centre (world frame)
  Eigen::Vector3f object_size = Eigen::Vector3f::Zero();  // its box: width (x), depth (y), height (z)
  bool size_guessed = false;  // MeshPlacement::size_guessed
  OrientedBox keypoint_box;
};

// Loads each mesh and puts it upright at its real size on z = 0 (placeMesh).
std::vector<Mesh> placeMeshes(const std::vector<TrainingMesh>& meshes, const TrainingParams& params);
// Per mesh, its index among the meshes of its category (TrainingScan::model_index).
std::vector<int> modelIndices(const std::vector<TrainingMesh>& meshes);

// Renders and describes every mesh from every view. `scenes`, when given, also receives each
// scan's rendered scene (index-aligned with the scans): evaluation recognises them as a user's
// frames, verification included.
std::vector<TrainingScan> scanMeshes(const std::vector<TrainingMesh>& meshes, const TrainingParams& params);
std::vector<TrainingScan> scanMeshes(const std::vector<TrainingMesh>& meshes, const std::vector<Mesh>& placed,
                                     const TrainingParams& params, std::vector<Scene>* scenes = nullptr);

// Everything after scanning (codebooks, votes, thresholds, boxes); exposed for evaluation.
// `background`: scans of background meshes (background.h), which weigh every category's codewords.
Model trainFromScans(const std::vector<TrainingScan>& scans, const std::vector<std::string>& categories,
                     const TrainingParams& params, const std::vector<const TrainingScan*>& background = {});

Model train(const std::vector<TrainingMesh>& meshes, const TrainingParams& params);

}  // namespace ism
