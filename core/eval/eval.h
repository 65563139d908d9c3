#pragma once
// Evaluation as in the seed (the 2012 thesis's evaluation protocol):
// (a) the baseline on synthetic scans: "hypothesis generated" tables and confusion matrices
//     for each codebook x activation x weighting combination the seed compared;
// (b) real scenes with hand-marked centres: TP/FP/FN, the seed's recognition rate
//     r = TP / (#objects + FP) and VOC-style average precision over the score.
// The front end runs once per scan or scene; every combination is evaluated on its features.
#include <array>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/common/upright_box.h"
#include "core/recognition/recognizer.h"
#include "core/training/trainer.h"

namespace ism {

using ProgressFn = std::function<void(const std::string&)>;

struct NamedStrategy {
  std::string name;  // "global 1nn+lw", as printed in the tables
  Strategy strategy;
};

// "global cutoff+aw": codebook, activation (k-NN as "<k>nn") and weighting.
std::string strategyName(const Strategy& strategy);
// The six combinations of the seed (global/separated x 1NN+LW, cutoff+LW, 1NN+AW), with the
// model's trained activation parameters; combinations whose codebook the model lacks are left out.
std::vector<NamedStrategy> seedCombinations(const Model& model);

// How a recognition is evaluated: the preset, and where the default preset's operating point
// is (the r, TP and FP columns count hypotheses at or above min_confidence; average precision
// ranks every hypothesis down to the lowest confidence recognition looks at).
struct EvalRecognition {
  RecognitionPreset preset = RecognitionPreset::kDefault;
  float min_confidence = RecognitionOptions{}.min_confidence;
  bool verify = true;  // default preset, where the scene is at hand
  bool shared_surface = true;  // SuppressionParams::shared_surface
  bool maps_in_3d = true;      // VerificationParams::maps_in_3d
  int icp_iterations = 0;      // VerificationParams::icp_iterations
  FitTerms fit_terms = FitTerms::kBoth;  // VerificationParams::fit_terms
  bool merge_support = true;   // SuppressionParams::merge_support
  bool top_support = true;     // SuppressionParams::top_support
  PeakCentre peak_centre = RecognitionOptions{}.peak_centre;
  SceneCheckParams scene_checks;  // RecognitionOptions::scene_checks
};

// recognizeFeatures() with the model's thresholds for the strategy. Seed preset: every peak above
// them for every category (passed_selection says whether it passed the box test), best first.
// Default preset: one answer per object down to the lowest confidence, most confident first.
// `scene`, the features' own, is what verification looks at (none: nothing verified).
// Throws Error(kInvalidInput) when the model lacks the strategy's codebook or threshold.
// With `more` models (an ensemble, recognizer.h): every model's answers fused.
std::vector<Hypothesis> hypothesesForFeatures(const Model& model, const Features& features, const Strategy& strategy,
                                              const EvalRecognition& recognition = {}, const Scene* scene = nullptr,
                                              const std::vector<const Model*>& more = {});

// ---------------------------------------------------------------------------------------------
// (a) Baseline on synthetic scans

struct MeshSplit {
  std::vector<TrainingMesh> train;
  std::vector<TrainingMesh> test;
};

// Per category (in order of first appearance), meshes sorted by path: the first
// `train_per_category` train, the next `test_per_category` test. Throws Error(kInvalidInput)
// naming the category when it has fewer meshes than that.
MeshSplit splitMeshes(const std::vector<TrainingMesh>& meshes, int train_per_category, int test_per_category);

// Counts with named rows and columns (row-major).
struct CountTable {
  std::vector<std::string> rows;
  std::vector<std::string> cols;
  std::vector<std::vector<int>> counts;
  int at(const std::string& row, const std::string& col) const;
};

struct BaselineCombination {
  std::string strategy;
  // Test category x model category: test scans where the model category produced at least one
  // hypothesis above its threshold, before box selection.
  CountTable generated;
  // Test category x (model category | "none"): the category of the best-scoring hypothesis
  // that passed box selection.
  CountTable confusion;
  double accuracy = 0;  // diagonal of `confusion` / test scans
  double recognition_ms = 0;  // all test scans, this combination
};

struct BaselineResult {
  std::vector<std::string> categories;  // model order; also the test rows
  int training_scans = 0;
  int test_scans = 0;
  double scan_seconds = 0;   // virtual scanning + front end of the test meshes
  double train_seconds = 0;  // train(): scanning the training meshes, codebooks, votes, thresholds, calibration
  std::vector<BaselineCombination> combinations;
};

// Evaluates `strategies` on test scans (one front end run per scan). Throws Error(kInvalidInput)
// when a test scan's category is not one of the model's. A scan's category is "generated" by a
// hypothesis of it or an alternative at or above the operating point. `scenes` (index-aligned
// with the scans, or empty) are what the default preset verifies hypotheses against.
BaselineResult evaluateBaseline(const Model& model, const std::vector<TrainingScan>& test_scans,
                                const std::vector<NamedStrategy>& strategies, const EvalRecognition& recognition = {},
                                const std::vector<Scene>& scenes = {});

// Scans train and test meshes, trains once as ism-train does (train(): with `params`' training
// shapes and calibration, which the default preset has and the seed's has not) and evaluates
// the seed's combinations on the test scans as scenes.
BaselineResult runBaseline(const MeshSplit& split, const TrainingParams& params, const EvalRecognition& recognition = {});

// ---------------------------------------------------------------------------------------------
// (b) Real scenes with ground truth (JSON: scene, cloud, objects with category, centre, size, yaw)

struct AnnotatedScene {
  std::string name;
  std::string json_path;
  std::string cloud_path;  // "cloud" of the JSON (default NAME.pcd), next to the JSON
  std::string frame;       // the JSON's "frame": how to read the coordinates
  std::vector<GroundTruthObject> objects;
  // Scene -> the gravity frame (z up) the boxes' sizes and yaws are given in: rows "axes_a",
  // "axes_b", "floor_normal" when the JSON has them (a hand-levelled camera frame), else the
  // identity (frames that are "z up").
  Eigen::Matrix3f to_gravity = Eigen::Matrix3f::Identity();
  // The data itself is gravity-levelled ("z up" in its frame), as a robot that knows its own pose
  // would send it; false when up was fitted by the annotator, so the recognizer has to find it.
  bool up_is_given = false;
};

// Throws Error(kNotFound) when the JSON or its cloud is missing, Error(kInvalidInput) naming the
// file and field when the JSON is malformed or lacks "objects".
AnnotatedScene readSceneAnnotation(const std::string& json_path);
// Folders (every *.json inside), .json files, or clouds (.pcd/.ply -> the .json beside them);
// the JSON paths in a stable order. Throws Error(kNotFound) for a path without ground truth.
std::vector<std::string> findSceneAnnotations(const std::vector<std::string>& inputs);

// Model category -> ground-truth categories it may match. Model categories without an entry
// match the ground-truth category of the same name.
using CategoryMapping = std::map<std::string, std::vector<std::string>>;
// office_chair, dining_chair -> chair; dining_table -> table | desk; couch -> sofa.
CategoryMapping defaultCategoryMapping();
// "model=gt1|gt2" sets (replaces) one entry. Throws Error(kInvalidInput) naming the text.
void addCategoryMapping(CategoryMapping& mapping, const std::string& spec);

// Normals need a sensor position. A cloud file may carry it (a PCD's VIEWPOINT: the sample
// scene and the project's synthetic scenes); single frames (Kinect, SUN RGB-D) have the camera
// at the origin of their frame; fused reconstructions (ScanNet) have none, so the viewpoint is
// put in the middle of the room at eye height (roomCentreViewpoint), so that floors face up and
// walls face into the room.
enum class ViewpointPolicy {
  kAuto,            // as recognition decides (mapViewpoint): the file's sensor pose, or the origin
                    // of a single view, or the middle of a map
  kOrigin,
  kRoomCentre,      // along the ground truth's up
};
ViewpointPolicy parseViewpointPolicy(const std::string& s);  // "auto", "origin", "room-centre"
Eigen::Vector3f sceneViewpoint(const AnnotatedScene& annotation, const Scene& scene, ViewpointPolicy policy,
                               float eye_height = 1.5f);

// One hypothesis as the matching rules see it.
struct ScoredDetection {
  float score = 0;
  Eigen::Vector3f position = Eigen::Vector3f::Zero();  // centroid of the supporting keypoints
  float radius = 0;  // 1/4 of the category's maximum box edge
  UprightBox box;    // in the scene's gravity frame
};
enum class MatchLabel {
  kTruePositive,
  kFalsePositive,
  kMergedFalsePositive,  // within `radius` of an FP already counted: counts once with it
};
// The seed's rule, greedy by descending score: a detection is a TP when an object not matched
// yet lies within its radius (the nearest one is taken), else an FP. Labels are index-aligned
// with `detections`.
std::vector<MatchLabel> matchDetections(const std::vector<ScoredDetection>& detections,
                                        const std::vector<Eigen::Vector3f>& objects);

// The 3D detection rule of SUN RGB-D and ScanNet (as VoteNet evaluates them), greedy by
// descending score: a detection is a TP when the object its box overlaps most has IoU >= min_iou
// and is not matched yet, else an FP. Returns is-TP flags index-aligned with `detections`.
std::vector<bool> matchDetectionsByIou(const std::vector<ScoredDetection>& detections,
                                       const std::vector<UprightBox>& objects, float min_iou);

// VOC-style (all points) AP of ranked detections (score, is TP) against `objects` ground-truth
// objects: area under the precision envelope over recall. NaN when there are no objects.
double averagePrecision(std::vector<std::pair<float, bool>> ranked, int objects);

// Counts of one ground-truth class (e.g. "chair"), fed by every model category mapped onto it.
// A model category also matches ground truth of its own name (synthetic scenes use the model's
// names).
struct ClassScore {
  std::string name;                           // ground-truth categories joined by '|'
  std::vector<std::string> model_categories;  // model categories mapped onto it
  int objects = 0, tp = 0, fp = 0, fn = 0;
  int scenes = 0;   // scenes scored
  double rate = 0;  // TP / (objects + FP); NaN when both are zero
  double ap = 0;    // NaN without objects
  // 3D boxes at IoU >= 0.25 in the gravity frame: AP, and the counts of every detection.
  double ap25 = 0;  // NaN without objects
  int tp25 = 0, fp25 = 0;
  std::vector<std::pair<double, double>> pr25;  // (recall, precision) down the ranking
  std::vector<std::pair<float, bool>> ranked25;  // every detection: (confidence, TP at IoU 0.25), best first
  // Per ground-truth object, what recognition came closest with: the scene, the largest 3D IoU of
  // any of the class's detections and that detection's confidence, and the distance from the
  // object's centre to the nearest detection's box centre (infinite without detections).
  struct ObjectOutcome {
    std::string scene;
    float best_iou = 0, best_iou_confidence = 0, nearest_distance = 0;
  };
  std::vector<ObjectOutcome> outcomes;
  // Every detection as ranked25 counts it, with what its category's calibration weighed
  // (tests/eval/domain_gap.py sets them beside the calibration rooms' peaks).
  struct Candidate {
    std::string scene, category;
    bool tp25 = false;
    float confidence = 0;  // what ranks the class's detections (rankingScore)
    float score = 0;
    int support = 0;
    bool verified = false;
    float fit = 0, profile_distance = 0;  // when verified
  };
  std::vector<Candidate> candidates;
};

// The score a class ranks its detections by: hypotheses of several model categories compete for
// one ground-truth class, so it has to mean the same for each of them.
float rankingScore(const Hypothesis& h);

// Matches hypotheses against ground truth scene by scene and accumulates per class. Only the
// model's category names and box statistics (maximum edge) are used.
class ClassScorer {
 public:
  ClassScorer(const Model& model, const CategoryMapping& mapping);
  // Hypotheses that failed box selection are ignored. Returns this scene's {TP, FP, FN} summed
  // over classes (the seed's rule); ground-truth objects of unmapped categories ("other") are
  // ignored. The boxes are compared in the gravity frame of `to_gravity` (scene -> gravity).
  // Hypotheses below `min_confidence` count towards AP@0.25 only.
  std::array<int, 3> addScene(const std::vector<GroundTruthObject>& objects,
                              const std::vector<Hypothesis>& hypotheses,
                              const Eigen::Matrix3f& to_gravity = Eigen::Matrix3f::Identity(),
                              float min_confidence = 0, const std::string& scene_name = "");
  std::vector<ClassScore> scores() const;

 private:
  struct Class {
    std::vector<std::string> gt_categories;
    std::vector<std::string> model_categories;
    int objects = 0, tp = 0, fp = 0, scenes = 0, tp25 = 0, fp25 = 0;
    std::vector<std::pair<float, bool>> ranked;  // counted detections: merged FPs count once
    std::vector<ClassScore::ObjectOutcome> outcomes;
    std::vector<ClassScore::Candidate> candidates;  // every detection, by 3D IoU (ranked25)
  };
  std::vector<Class> classes_;
  std::map<std::string, float> radius_;  // model category -> 1/4 of its maximum box edge
};

struct RealCombination {
  std::string strategy;
  std::vector<ClassScore> classes;
  std::vector<std::array<int, 3>> scene_tp_fp_fn;  // per scene, summed over classes
};

struct SceneRun {
  std::string name;
  size_t points = 0;
  size_t surface_points = 0;
  size_t keypoints = 0;
  Eigen::Vector3f viewpoint = Eigen::Vector3f::Zero();
  double load_ms = 0;
  double front_end_ms = 0;
  std::vector<double> recognition_ms;  // per strategy
};

struct RealEvalParams {
  std::vector<NamedStrategy> strategies;
  EvalRecognition recognition;
  CategoryMapping mapping = defaultCategoryMapping();
  ViewpointPolicy viewpoint = ViewpointPolicy::kAuto;
  float eye_height = 1.5f;
  bool give_up = true;  // pass a gravity-levelled scene's up (AnnotatedScene::up_is_given)
  // The given up turned by this angle towards the azimuth (from the scene's gravity-frame x to its
  // y): the answers of maps are chaotic in their up (a change far below the sensor's noise moves
  // keypoints across the grids), so a step is judged over several such draws (tilt_spread.py).
  float up_tilt_deg = 0.0f;
  float up_tilt_azimuth_deg = 0.0f;
  ProgressFn progress;  // one line per scene; may be empty
  // More models with the evaluated one's categories and front end: the ensemble is evaluated.
  std::vector<const Model*> more_models;
};

struct RealResult {
  std::vector<SceneRun> scenes;
  std::vector<RealCombination> combinations;  // in the order of params.strategies
};

// The up passed to a gravity-levelled scene: its annotated up turned by params' tilt.
Eigen::Vector3f givenUp(const AnnotatedScene& scene, const RealEvalParams& params);

// The mean of AP@0.25 over the classes that have objects; NaN when none has.
double meanAp25(const RealCombination& combination);

// Counts accumulate over all scenes; AP ranks all hypotheses of all scenes of a class by score.
RealResult evaluateRealScenes(const Model& model, const std::vector<AnnotatedScene>& scenes,
                              const RealEvalParams& params);

// ---------------------------------------------------------------------------------------------
// Output

// Aligned text tables for a terminal.
std::string formatBaseline(const BaselineResult& result);
std::string formatReal(const RealResult& result);
// PNG bytes: the precision-recall curves (3D IoU >= 0.25) of each class with objects.
std::string renderPrecisionRecall(const RealCombination& combination);
// JSON documents (NaN as null).
std::string baselineToJson(const BaselineResult& result);
std::string realToJson(const RealResult& result);

}  // namespace ism
