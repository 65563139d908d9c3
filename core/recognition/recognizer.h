#pragma once
// Recognition: features -> codeword activations -> weighted votes in a 3D Hough space per
// category -> every local maximum above the threshold -> box selection -> hypotheses.
// The stages live in their own files: voting.h (the votes), hough_space.h (bins and peaks),
// box_selection.h (the learned box limits); this file plans a call and chains them.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "core/common/types.h"
#include "core/frontend/frontend.h"
#include "core/model/model.h"
#include "core/recognition/box_selection.h"
#include "core/recognition/hough_space.h"
#include "core/recognition/hypothesis.h"
#include "core/recognition/voting.h"

namespace ism {

struct RecognitionOptions {
  Strategy strategy;                    // codebook type, activation, weighting: per call
  std::vector<std::string> categories;  // empty = every category of the model
  // Overrides the model's leave-one-out threshold for the chosen strategy when set.
  std::optional<float> min_score;
  int max_hypotheses = 0;               // 0 = no limit; best first (Hypothesis::relativeScore)
  bool box_selection = true;            // false: keep hypotheses that fail the box test too
  bool return_keypoints = false;        // fill Hypothesis::support_keypoints
  bool keep_votes = false;              // fill RecognitionResult::votes (debug PLY)
  ShouldStop should_stop;               // polled between stages and in long loops
};

struct RecognitionResult {
  std::vector<Hypothesis> hypotheses;  // passed selection, best first
  std::vector<Hypothesis> rejected;    // above threshold but failed box selection
  StageTimings timings;
  size_t input_points = 0;
  size_t surface_points = 0;
  size_t keypoints = 0;
  std::vector<Eigen::Vector3f> keypoint_positions;  // when keep_votes
  std::vector<Vote> votes;                          // when keep_votes
};

// Throws Error(kNotFound) for an unknown category, Error(kInvalidInput) for a strategy the
// model was not trained for (e.g. separated codebook missing) or a scene with no points left.
RecognitionResult recognize(const Model& model, const Scene& scene, const RecognitionOptions& options);

// recognize() after the front end: activation, voting, peak search and box selection on
// already extracted features (evaluation runs the front end once and every strategy on it).
// Same errors as recognize() except for the scene; the point counts of the result stay 0.
RecognitionResult recognizeFeatures(const Model& model, const Features& features, const RecognitionOptions& options);

}  // namespace ism
