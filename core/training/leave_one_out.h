#pragma once
// Leave-one-out thresholds (the seed's rule): the codebook stays fixed, the held-out model's
// votes are removed, and each of its scans is scored at its true centre; the threshold is
// mean - std over those scores, but at least threshold_floor times the mean.
#include <string>
#include <vector>

#include "core/codebook/codebook.h"
#include "core/model/model.h"
#include "core/training/trainer.h"
#include "core/training/votes.h"

namespace ism {

// One category's training data under one codebook.
struct LeaveOneOutInput {
  const std::string& category;
  CodebookType codebook_type;
  const Codebook& codebook;
  const std::vector<TrainingVote>& votes;        // of every model, under `codebook`
  const std::vector<const TrainingScan*>& scans;  // of the category
  int models;                                     // model_index < models
  float bin_size;                                 // the category's Hough bin
  VotingParams voting{};                          // how the votes are cast
  std::vector<float> codeword_weights{};          // VoteTable::codeword_weights
};

// The threshold of one strategy and the held-out scores behind it.
struct LeaveOneOutThreshold {
  ThresholdKey key;
  double mean = 0, std = 0;  // of the held-out scores
  float threshold = 0;       // max(mean - std, threshold_floor * mean)
  bool floored = false;      // mean - std fell below threshold_floor * mean
};

// A threshold for each of `activations` (in order) with each weighting (CW, LW, AW), in that
// order. threshold_floor is TrainingParams::threshold_floor; `threads` run the held-out scans.
std::vector<LeaveOneOutThreshold> leaveOneOutThresholds(const LeaveOneOutInput& input,
                                                        const std::vector<ActivationParams>& activations, float threshold_floor,
                                                        int threads);

}  // namespace ism
