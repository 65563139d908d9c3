#pragma once
// Calibration: a confidence that means the same for every category. Vote scores are not
// comparable across categories (a couch's votes spread wider than a chair's) nor between the
// training scans and the world (a held-out training scan shows the whole object up close, a
// room shows part of it among clutter). So each category's scores are mapped to a probability,
// fitted to what the model finds in scenes that look like the world: rendered rooms with a
// floor, walls, boxes and the manifest's background meshes, furniture the model was not trained
// on (k-fold over the training objects, votes of the held-out fold left out), cameras at a
// robot's and a person's height.
// Every peak of a category that passes recognition's checks of the scene around it
// (scene_checks.h) is labelled by whether an object of that category is there (labelPeak); a
// logistic regression over the log score, the log score per supporting keypoint and, where the
// model keeps training shapes, the verification's fit and shape profile distance gives the confidence (Calibration; Platt, "Probabilistic outputs for support vector machines", 1999).
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "core/model/model.h"
#include "core/recognition/hypothesis.h"
#include "core/scanner/mesh.h"
#include "core/scanner/scanner.h"
#include "core/training/trainer.h"

namespace ism {

// One training mesh as the calibration scenes place it.
struct PlacedObject {
  std::string category;
  int model_index = 0;  // TrainingScan::model_index
  const Mesh* mesh = nullptr;  // upright on z = 0 (placeMesh)
};

// One rendered room of the calibration.
struct CalibrationRoom {
  SyntheticScene scene;
  std::vector<std::string> categories;  // of scene.objects, furniture first, then clutter ("")
  std::vector<SceneObject> objects;     // what stands in it, walls and floor aside, as scene shows them
  SyntheticSceneParams view;            // scene's camera and sensor
};

// Up to params.max_objects of `furniture` (the fold's held-out objects) standing apart on the
// floor, a wall or two behind them, boxes, and up to params.background_objects of `background`
// (beds, cabinets, shelves: real rooms' false peaks stand on such furniture, which fits a couch's
// or a table's shape far better than a box does), seen by `noise`'s sensor from a random camera.
// A share of the rooms (params.grouped_rooms) shows instead one of `tables` (those of `furniture`
// that are flat-topped) with the rest of `furniture` pulled up to it.
CalibrationRoom composeCalibrationRoom(const std::vector<const PlacedObject*>& furniture,
                                       const std::vector<const PlacedObject*>& background,
                                       const CalibrationParams& params, const NoiseParams& noise, std::mt19937& rng,
                                       const std::vector<const PlacedObject*>& tables = {});

// The room as a robot's mapping stack or a room scan (ScanNet) gives it: params.map_views frames
// from cameras 2-3 m around its middle at 1.0-1.8 m, fused per params.map_spacing cube, cropped
// to the room's walls and sampled down to a number of points log-uniform in
// [params.map_points_min, map_points_max]; no image grid and no pose, z up, as a map is sent.
Scene calibrationMap(const CalibrationRoom& room, const CalibrationParams& params, std::mt19937& rng);

// One labelled peak: its score and support and whether an object of its category was there.
struct CalibrationSample {
  int category = 0;  // index into Model::categories
  float score = 0;
  int support = 0;
  bool positive = false;
  float fit = 0.5f;  // Verification::fit(), 0.5 when not verified
  float profile_distance = 1.0f;  // Verification::profile_distance, 1 when not verified
  bool cloud = false;  // found in a room seen as an unorganized point sample, or as a map
  int fold = 0;        // the calibration fold whose rooms it was found in
  // The nearest global codeword of each supporting keypoint, when the calibration learns codeword
  // weights (CalibrationParams::learned_weights)
  std::vector<int> codewords;
};

// A category's kind: the last word of its name ("office_chair" and "dining_chair" are chairs,
// "dining_table" a table, "couch" a couch), as the evaluation's classes group them (eval.h).
std::string categoryKind(const std::string& category);

// What a rendered room's peak teaches its category's calibration.
enum class PeakLabel { kPositive, kNegative, kLeftOut };

// Labels a peak against the room's furniture (`objects[o]` of category `categories[o]`, "" for
// clutter) by the evaluation's rules (its centre within a quarter of the object's longest side, or
// the upright boxes overlapping by a quarter): positive on an object of the peak's category that no
// better peak of it took (`matched`, which it then marks); with `kinds`, left out on an object of
// another category of its kind (a dining chair's peak on an office chair: neither the chair it is
// nor the category it names; CalibrationParams::kinds); otherwise a negative, a second peak on a
// taken object too (recognition would answer that object twice).
PeakLabel labelPeak(const Hypothesis& peak, const std::vector<std::string>& categories,
                    const std::vector<GroundTruthObject>& objects, const Eigen::Matrix3f& to_gravity, bool kinds,
                    std::vector<bool>& matched);

// The peaks of the calibration scenes, every category's. `scans` are the training scans the
// model was trained from (their votes are re-made per fold).
std::vector<CalibrationSample> calibrationSamples(const Model& model, const std::vector<TrainingScan>& scans,
                                                  const std::vector<PlacedObject>& objects,
                                                  const TrainingParams& params);

// A peak's inputs of the calibration: ln score, ln(score / support), the fit and, with
// `shape_profile`, the profile distance (else 0).
Eigen::Vector4d calibrationInputs(const CalibrationSample& s, bool shape_profile = true);

// Logistic regression of `positive` on ln score, ln(score / support), the fit and, with
// `shape_profile`, the profile distance (Newton's method with step halving, a little ridge so that
// a separable category still gets finite slopes). Throws Error(kInvalidInput) without both
// positives and negatives.
Calibration fitCalibration(const std::vector<CalibrationSample>& samples, bool shape_profile = true);

// Fits each of `groups` (a category's samples; `profiles`: whether it weighs the profile) as
// fitCalibration does, but with its slopes drawn towards the slopes all groups share, each with
// its own intercept (partial pooling: a Gaussian prior of `spread` per slope around the pooled
// fit; Gelman and Hill, "Data Analysis Using Regression and Multilevel/Hierarchical Models", 2007,
// ch. 12). The spread is the one of `spreads` whose fits best predict each fold's samples
// (CalibrationSample::fold) from the other folds'; 0 among them fits each group alone, and so
// does an empty `spreads`. `chosen` gets the spread used. A group without both labels gets none.
std::vector<std::optional<Calibration>> fitCalibrations(const std::vector<std::vector<CalibrationSample>>& groups,
                                                        const std::vector<bool>& profiles, const std::vector<double>& spreads,
                                                        double* chosen = nullptr);

// Fits every category of `model` that has positives and negatives among the samples, the
// frames' samples into its calibration and the point samples' (and maps') into its
// cloud_calibration; the others keep none. Progress lines go to params.progress.
void calibrate(Model& model, const std::vector<TrainingScan>& scans, const std::vector<PlacedObject>& objects,
               const TrainingParams& params);

}  // namespace ism
