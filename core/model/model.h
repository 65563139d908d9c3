#pragma once
// A trained set of Implicit Shape Models: the front end it was trained with, the codebook(s),
// per category the votes stored under each codeword, detection thresholds and box statistics.
// Saved as the versioned Protobuf format of proto/ism/v1/model.proto (model_file.h).
#include <algorithm>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "core/codebook/codebook.h"
#include "core/frontend/params.h"

namespace ism {

enum class CodebookType { kGlobal, kSeparated };
enum class VoteWeighting {
  kCategorization,  // CW: every vote weighs 1
  kLocalization,    // LW: 1/M * 1/|Occ[i]|, each keypoint's votes sum to 1
  kActivation,      // AW: (1 - d/2) * LW
};

const char* toString(CodebookType t);
const char* toString(ActivationStrategy s);
const char* toString(VoteWeighting w);
// Short names used by CLIs and the service: "global"/"separated", "knn"/"cutoff", "cw"/"lw"/"aw".
CodebookType parseCodebookType(const std::string& s);
ActivationStrategy parseActivationStrategy(const std::string& s);
VoteWeighting parseVoteWeighting(const std::string& s);

// The strategy of one recognition call (the seed compares these combinations).
struct Strategy {
  CodebookType codebook = CodebookType::kGlobal;
  ActivationParams activation;
  VoteWeighting weighting = VoteWeighting::kLocalization;
};

struct ThresholdKey {
  CodebookType codebook;
  ActivationStrategy activation;
  VoteWeighting weighting;
  bool operator<(const ThresholdKey& o) const {
    return std::tie(codebook, activation, weighting) < std::tie(o.codebook, o.activation, o.weighting);
  }
  bool operator==(const ThresholdKey& o) const {
    return codebook == o.codebook && activation == o.activation && weighting == o.weighting;
  }
};

// The frame a keypoint's votes are stored and cast in.
enum class VoteFrame {
  // The SHOT local reference frame (the seed's). Fully rotation invariant, and as unstable as
  // the LRF's axes: on flat or symmetric supports their signs are left to chance.
  kLrf,
  // Upright: z is up, x the keypoint's surface normal made horizontal, or where the surface is
  // horizontal the direction into its support. Furniture stands upright, so only its heading is
  // unknown, and votes keep their height exactly (Velizhev, Shapovalov and Schindler, "Implicit
  // shape models for object detection in 3D point clouds", ISPRS 2012, vote in the ground plane
  // for the same reason).
  kUpright,
};
const char* toString(VoteFrame f);

// How votes are cast; stored with the model because its vote tables were made that way.
struct VotingParams {
  VoteFrame frame = VoteFrame::kLrf;
  // With the floor known, a keypoint casts only the votes of training keypoints whose height
  // above the floor was within this of its own (m): furniture stands on the floor, so a part seen
  // at 1.6 m is no chair's seat. 0 turns the test off.
  float height_tolerance = 0;
  // What the height test does with a codeword's votes at other heights. false: they are lost
  // mass (each kept vote weighs 1 / all of the codeword's votes), so a codeword seen at many
  // heights votes little wherever it fires. true: the keypoint's weight spreads over the votes at
  // its height, p(centre | codeword, height) rather than p(centre, height | codeword).
  bool height_normalized = false;
};

// Votes stored under each codeword, CSR layout: votes of codeword i are
// vectors[offsets[i] .. offsets[i+1]), each in the frame (VotingParams::frame) of the keypoint
// that cast it.
struct VoteTable {
  std::vector<uint32_t> offsets;  // codebook size + 1 entries
  std::vector<Eigen::Vector3f> vectors;
  // Per vote, the height above the floor of the training keypoint that cast it, ascending within
  // each codeword; empty when the model was trained without heights.
  std::vector<float> heights;
  // Upright votes only, per vote: which training object cast it (an index into
  // CategoryModel::objects) and that object's heading in the vote frame (rad), so that the votes
  // a peak gathers also say how large the object is and which way it is turned.
  std::vector<uint16_t> objects;
  std::vector<float> headings;
  // Per codeword, how much its votes count, in (0, 1]: how much more often the category's
  // training keypoints activate it than background does (background.h); empty: every codeword
  // counts fully (models trained without background meshes).
  std::vector<float> codeword_weights;
  size_t occurrences(int codeword) const { return offsets[codeword + 1] - offsets[codeword]; }
  float codewordWeight(int codeword) const {
    return codeword_weights.empty() ? 1.0f : codeword_weights[static_cast<size_t>(codeword)];
  }
  bool empty() const { return vectors.empty(); }
};

// Oriented-box limits learned from the training scans' keypoint boxes (mean -/+ std).
struct BoxStats {
  float min_volume = 0;
  float max_volume = 0;
  float max_edge = 0;
  // The raw statistics behind the limits, for reports.
  float mean_volume = 0, std_volume = 0, mean_max_edge = 0, std_max_edge = 0;
};

// Leave-one-out statistics behind a threshold: the held-out models' scores at their centres.
struct ThresholdStats {
  float mean = 0;
  float std = 0;
};

// One training mesh as placed: upright on the floor, its box along its own x (width), y (depth).
struct TrainingObject {
  Eigen::Vector3f size = Eigen::Vector3f::Zero();  // width, depth, height (m)
  float center_height = 0;                          // of its box centre above the floor (m)
  // Points on the mesh's surface as placed (its box centred on x = y = 0, standing on z = 0), in
  // random order so that any prefix is an even sample: what verification fits to the scene.
  std::vector<Eigen::Vector3f> surface;
  // Sized to its category's typical size, its own unknown (MeshPlacement::size_guessed): the
  // footprint prior (top_extent.h) leaves it out.
  bool size_guessed = false;
};

// A category's confidence for a peak of score s gathered from n supporting keypoints, whose
// verification fit is v (0.5 unverified) and whose surface lies at a profile distance g from the
// training shapes' (Verification::profile_distance, 1 unverified):
// 1 / (1 + exp(-(a ln s + c ln(s / n) + d v + e g + b))), fitted to the peaks the model finds in synthetic
// scenes of held-out training objects among clutter. s / n, the vote mass per supporting
// keypoint, says how well the keypoints agree whatever their number: the same object seen from
// farther, or by a sparser sensor, has fewer keypoints but agrees as well.
struct Calibration {
  float a = 0, b = 0, c = 0;
  float d = 0;  // 0 in models calibrated without verification
  float e = 0;  // 0 in models calibrated without the shape profile
  // Peaks below this score were not looked at when fitting: recognition does not look at them.
  float min_score = 0;
  int positives = 0, negatives = 0;  // the peaks it was fitted to
  float confidence(float score, int support, float fit = 0.5f, float profile_distance = 1.0f) const;
};

struct CategoryModel {
  std::string name;
  float bin_size = 0.1f;  // Hough bin edge (m)
  BoxStats box;
  std::optional<Codebook> own_codebook;  // separated codebook, when trained
  VoteTable global_votes;                // votes under the global codebook's codewords
  VoteTable own_votes;                   // votes under own_codebook's codewords
  std::map<ThresholdKey, float> thresholds;  // leave-one-out mean - std per combination, floored
  std::map<ThresholdKey, ThresholdStats> threshold_stats;  // behind `thresholds`; empty in older files
  int training_models = 0;
  int training_scans = 0;
  // Per training model (TrainingScan::model_index); empty in files written before they were kept.
  std::vector<TrainingObject> objects;
  std::optional<Calibration> calibration;  // models trained before calibration have none
  // The calibration for scenes without an image grid (Features::organized false), where the
  // model has one: clouds reach lower scores than depth frames of the same furniture.
  std::optional<Calibration> cloud_calibration;
};

// Whether `value` lies within the range `of_object` takes over the category's training objects
// that `counts` admits (all by default), give or take `slack`: recognition's priors from the
// training meshes. True without such objects (a model written before they were kept has nothing
// to bound it by).
template <typename OfObject, typename Counts>
bool withinTrainingRange(const CategoryModel& category, OfObject of_object, float value, float slack, Counts counts) {
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  for (const auto& o : category.objects) {
    if (!counts(o)) continue;
    lo = std::min(lo, of_object(o));
    hi = std::max(hi, of_object(o));
  }
  if (lo > hi) return true;
  return value >= lo - slack && value <= hi + slack;
}
template <typename OfObject>
bool withinTrainingRange(const CategoryModel& category, OfObject of_object, float value, float slack) {
  return withinTrainingRange(category, of_object, value, slack, [](const TrainingObject&) { return true; });
}

struct Provenance {
  std::vector<std::string> meshes;  // "category<TAB>path<TAB>credit"
  int scans = 0;
  std::string created;       // ISO 8601 UTC
  std::string code_version;  // git describe of the training build
  std::string command;       // how it was trained
};

struct Model {
  FrontEndParams front_end;
  VotingParams voting;
  // Activation parameters the thresholds were computed with (kNN k and cutoff distance).
  ActivationParams trained_knn{ActivationStrategy::kKnn, 1, 0.25f};
  ActivationParams trained_cutoff{ActivationStrategy::kCutoff, 1, 0.25f};
  std::optional<Codebook> global_codebook;
  std::vector<CategoryModel> categories;
  Provenance provenance;
  // The same training with other draws of its randomness (ism-train --draws): models of the same
  // categories and front end, with the global codebook alone and without draws of their own.
  // Recognition with the default preset and the global codebook answers with this model and its
  // draws together, as an ensemble (recognizer.h); otherwise with this one alone.
  std::vector<Model> draws;

  const CategoryModel* find(const std::string& category) const;
  // Whether `other` has this model's categories, by name, in the same order (an ensemble's and a
  // file's draws must: their plans index categories alike).
  bool sameCategories(const Model& other) const;
  bool has(CodebookType type) const;
  // Keep a caller's up whatever the scene's floor shows (GravityParams::given_up_kept_deg), in
  // this model and its draws alike (ism-detect, ism-eval --trust-given-up).
  void trustGivenUp();
};

}  // namespace ism
