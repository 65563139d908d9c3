#pragma once
// The votes training stores: each training keypoint's vector to its object's centre, in the
// keypoint's local reference frame, under the codeword its descriptor activates (1-NN). The
// model each vote came from is kept until the table is packed, so that leave-one-out can
// leave a model's votes out.
#include <vector>

#include "core/codebook/codebook.h"
#include "core/model/model.h"
#include "core/training/trainer.h"

namespace ism {

struct TrainingVote {
  int codeword;
  int model;  // TrainingScan::model_index
  Eigen::Vector3f vector;
};

// The votes of `scans` (one category's) under `codebook`, scan by scan, keypoint by keypoint.
std::vector<TrainingVote> trainingVotes(const std::vector<const TrainingScan*>& scans, const Codebook& codebook);

// CSR table of the votes, optionally without those of model `excluded`.
VoteTable packVotes(const std::vector<TrainingVote>& votes, int codebook_size, int excluded = -1);

}  // namespace ism
