#pragma once
// An ensemble: several models of the same categories, each trained with its own draw of
// training's randomness (the codebook's k-means start, the training scans' sensor noise, the
// calibration rooms), answer one scene together. One model's answers move with its draw as much
// as most steps of the method change them; their average does not (bagging: Breiman, "Bagging
// predictors", Machine Learning 1996; Hough forests average their trees' votes the same way,
// Gall and Lempitsky, CVPR 2009). docs/EVALUATION.md ("What the draws of training change")
// measures it. The front end runs once; each model then votes, verifies and checks on its own,
// and their answers are fused.
#include <vector>

#include "core/common/types.h"
#include "core/frontend/frontend.h"
#include "core/model/model.h"
#include "core/recognition/recognizer.h"

namespace ism {

struct EnsembleParams {
  // Two models' answers are one object's when their categories match and their upright boxes
  // overlap by at least this much (IoU in the gravity frame).
  float min_iou = 0.3f;
};

// Each model's answers down to confidence 0.01, fused: per category, answers whose boxes overlap
// by params.min_iou, at most one per model, are one; its confidence is the mean over the models
// (0 for a model without an answer there), its box, fit and alternatives those of its most
// confident model's answer. Then one answer per object across categories, options.min_confidence
// and options.max_hypotheses, as recognize() does. One model: recognize() itself.
// Throws Error(kInvalidInput) for no models, models whose front ends or categories differ, or
// the seed preset; otherwise as recognize().
RecognitionResult recognizeEnsemble(const std::vector<const Model*>& models, const Scene& scene,
                                    const RecognitionOptions& options, const EnsembleParams& params = {});

// The same on features already extracted from `scene` with the models' front end.
RecognitionResult recognizeEnsembleFeatures(const std::vector<const Model*>& models, const Features& features,
                                            const RecognitionOptions& options, const Scene* scene,
                                            const EnsembleParams& params = {});

}  // namespace ism
