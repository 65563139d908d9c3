#pragma once
// The votes training stores: each training keypoint's vector to its object's centre, in the
// keypoint's vote frame (its LRF, or upright), under the codeword its descriptor activates
// (1-NN), with the keypoint's height above the floor when the scan has one. The model each vote
// came from is kept until the table is packed, so that leave-one-out can leave a model's votes
// out.
#include <vector>

#include "core/codebook/codebook.h"
#include "core/model/model.h"
#include "core/training/trainer.h"

namespace ism {

struct TrainingVote {
  int codeword;
  int model;  // TrainingScan::model_index
  Eigen::Vector3f vector;
  float height = 0;  // of the keypoint above the floor; NaN when the scan has no floor
  // Upright votes: the object's heading (its x axis) in the vote frame, rad; NaN otherwise.
  float heading = 0;
};

// The votes of `scans` (one category's) under `codebook`, scan by scan, keypoint by keypoint.
std::vector<TrainingVote> trainingVotes(const std::vector<const TrainingScan*>& scans, const Codebook& codebook,
                                        VoteFrame frame = VoteFrame::kLrf);

// CSR table of the votes, optionally without those of model `excluded`. When every vote has a
// height, the table keeps them, each codeword's votes in ascending height (stable); when every
// vote has a heading, the table keeps headings and models (as TrainingObject indices).
VoteTable packVotes(const std::vector<TrainingVote>& votes, int codebook_size, int excluded = -1);
// The same without the votes of every model m with held_out[m] (models beyond it are kept).
VoteTable packVotes(const std::vector<TrainingVote>& votes, int codebook_size, const std::vector<bool>& held_out);

}  // namespace ism
