#pragma once
// An ensemble: several models of the same categories, each trained with its own draw of
// training's randomness (the codebook's k-means start, the training scans' sensor noise, the
// calibration rooms), answer one scene together. One model's answers move with its draw as much
// as most steps of the method change them; their average does not (bagging: Breiman, "Bagging
// predictors", Machine Learning 1996; Hough forests average their trees' votes the same way,
// Gall and Lempitsky, CVPR 2009). docs/EVALUATION.md ("What the draws of training change")
// measures it. recognizer.h chains it: the front end runs once, each model votes and finds its
// peaks, this stage groups the models' peaks by object, each model verifies its own peak in a
// group, and the group's confidence is the mean of the models'.
#include <vector>

#include <Eigen/Core>

#include "core/recognition/hypothesis.h"

namespace ism {

struct EnsembleParams {
  // Two models' peaks are one object's when their upright boxes overlap by at least this much
  // (IoU in the gravity frame).
  float min_iou = 0.3f;
};

// One object as the models see it: per model, the index of its peak there or -1.
struct PeakGroup {
  std::vector<int> peak;
  int best = 0;  // the model whose peak there is the most confident
};

// Groups one category's peaks of each model (peaks[m]: model m's, each with its confidence and
// upright box) by object: the peaks, most confident first, each join the group whose first peak's
// box overlaps theirs most, by params.min_iou at least, and holds no peak of their model yet, or
// start one. Groups come in the order of their first peaks. One model: one group per peak, in
// the peaks' order of confidence.
std::vector<PeakGroup> groupPeaks(const std::vector<std::vector<Hypothesis>>& peaks, const Eigen::Matrix3f& to_gravity,
                                  const EnsembleParams& params = {});

}  // namespace ism
