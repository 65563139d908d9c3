#pragma once
// Recognition: features -> codeword activations -> weighted votes in a 3D Hough space per
// category -> every local maximum above the category's threshold -> a confidence, an upright box
// and the category's priors per peak -> one answer per object -> hypotheses. The seed's preset
// ends with its box selection instead. The stages live in their own files: voting.h (the votes),
// hough_space.h (bins and peaks), upright_boxes.h (boxes from the training objects),
// suppression.h (one answer per object), box_selection.h (the seed's learned box limits); this
// file plans a call and chains them.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "core/common/types.h"
#include "core/frontend/frontend.h"
#include "core/model/model.h"
#include "core/recognition/box_selection.h"
#include "core/recognition/ensemble.h"
#include "core/recognition/hough_space.h"
#include "core/recognition/hypothesis.h"
#include "core/recognition/scene_checks.h"
#include "core/recognition/suppression.h"
#include "core/recognition/verification.h"
#include "core/recognition/voting.h"

namespace ism {

enum class RecognitionPreset {
  // Confidence from the category's calibration, upright boxes and priors from the training
  // objects, one answer per object.
  kDefault,
  // The seed's: every peak above the leave-one-out threshold that passes the box selection,
  // ranked by score over threshold.
  kSeed,
};
const char* toString(RecognitionPreset p);
RecognitionPreset parseRecognitionPreset(const std::string& s);  // "default" or "seed"

struct RecognitionOptions {
  Strategy strategy;                    // codebook type, activation, weighting: per call
  RecognitionPreset preset = RecognitionPreset::kDefault;
  std::vector<std::string> categories;  // empty = every category of the model
  // Default preset: hypotheses below this confidence are dropped. At most 0.99; below 0.01 it
  // is 0.01, since peaks less likely than that are not looked at.
  // Why 0.3 and not 0.5: the seed's measure r = TP / (objects + FP) counts a false answer as
  // much as a missed object, so an answer right with probability p raises r when
  // p > r / (1 + r). That is 0.5 only for a perfect detector; for r of 0.3-0.5 (the
  // issues' targets) it is 0.23-0.33. docs/EVALUATION.md, "The default operating point".
  float min_confidence = 0.3f;
  // Overrides the score every peak must exceed when set: the model's leave-one-out threshold for
  // the strategy (seed preset) or the score of min_confidence (default preset).
  std::optional<float> min_score;
  int max_hypotheses = 0;               // 0 = no limit; best first
  // Default preset: merge and compete overlapping hypotheses (suppression.h); false keeps every
  // peak above the threshold (calibration labels them one by one).
  bool one_answer_per_object = true;
  // Default preset: where a peak is centred in its bin (hough_space.h); the seed preset centres
  // it on its bin's own votes. Training's calibration rooms centre their peaks with this default,
  // so that the confidence is learned on the peaks recognition finds.
  PeakCentre peak_centre = PeakCentre::kNeighbourhood;
  SuppressionParams suppression;
  // Default preset: check each hypothesis against the scene's depth with the category's training
  // shapes (verification.h), where the model keeps them; the fit enters the confidence and the
  // box becomes the best fitting shape's.
  bool verify = true;
  VerificationParams verification;
  // Default preset, verified hypotheses: checked against the scene around them (scene_checks.h).
  // A table's box spans the scene's top surface there; a table without a top, with nothing seen
  // under it, deeper or shallower, lower or higher than the training tables', a chair or couch
  // with too short a run at seat height, with little measured at seat height over its footprint or
  // with surface standing over its top, and any hypothesis in a map with bare floor in the middle
  // of its footprint are rejected; a couch over a level top is refuted. Across categories, of a
  // couch and a table whose box covers a third of its footprint the less confident goes
  // (seat_under_top.h).
  SceneCheckParams scene_checks;
  // Default preset, an ensemble (recognizeEnsemble): which models' peaks are one object's.
  EnsembleParams ensemble;
  bool box_selection = true;            // seed preset; false: keep hypotheses that fail the box test too
  bool return_keypoints = false;        // fill Hypothesis::support_keypoints
  bool keep_votes = false;              // fill RecognitionResult::votes (debug PLY)
  ShouldStop should_stop;               // polled between stages and in long loops
};

struct RecognitionResult {
  std::vector<Hypothesis> hypotheses;  // passed selection, best first
  // Above threshold but failed the box selection (seed preset) or the category's priors (default)
  std::vector<Hypothesis> rejected;
  std::optional<Gravity> gravity;      // up and the floor, when the front end found them
  // Where the scene was looked at from: its sensor origin, or for a map seen from nowhere the
  // middle of its points (lookedAt)
  Eigen::Vector3f viewpoint = Eigen::Vector3f::Zero();
  StageTimings timings;
  size_t input_points = 0;
  size_t surface_points = 0;
  size_t keypoints = 0;
  size_t verified = 0;  // peaks verified against the scene, over an ensemble's models
  std::vector<Eigen::Vector3f> keypoint_positions;  // when keep_votes
  std::vector<Vote> votes;                          // when keep_votes
};

// The model and its draws (Model::draws) answer together, as recognizeEnsemble's models do
// (with the default preset and the global codebook).
// Throws Error(kNotFound) for an unknown category, Error(kInvalidInput) for a strategy the
// model was not trained for (e.g. separated codebook missing) or a scene with no points left.
RecognitionResult recognize(const Model& model, const Scene& scene, const RecognitionOptions& options);

// recognize() after the front end: activation, voting, peak search and box selection on
// already extracted features (evaluation runs the front end once and every strategy on it).
// `scene`, the one the features come from, is what verification looks at; without it nothing is
// verified. Same errors as recognize() except for the scene; the point counts of the result stay 0.
RecognitionResult recognizeFeatures(const Model& model, const Features& features, const RecognitionOptions& options,
                                    const Scene* scene = nullptr);

// recognize() with several models of the same categories and front end, each trained with its
// own draw of training's randomness (ensemble.h): the front end runs once, each model votes and
// finds its peaks down to confidence 0.01, each category's peaks are grouped by object (at most
// one per model), and in each group whose mean best possible confidence reaches min_confidence
// each model verifies and checks its own peak. The group's answer is its most confident model's,
// at the mean of the models' confidences (0 for a model without an answer there); one answer per
// object follows as for one model. Each model's draws (Model::draws) are models of the ensemble too, except
// with the seed's preset or a separated codebook.
// Throws Error(kInvalidInput) for no models, models whose front ends or categories differ, or
// several models with the seed preset; otherwise as recognize().
RecognitionResult recognizeEnsemble(const std::vector<const Model*>& models, const Scene& scene,
                                    const RecognitionOptions& options);

// The same on features already extracted from `scene` with the models' front end.
RecognitionResult recognizeEnsembleFeatures(const std::vector<const Model*>& models, const Features& features,
                                            const RecognitionOptions& options, const Scene* scene = nullptr);

}  // namespace ism
