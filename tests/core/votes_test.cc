#include "core/training/votes.h"

#include <gtest/gtest.h>

namespace ism {
namespace {

TEST(TrainingVotes, EachKeypointVotesForTheCentreInItsFrameUnderItsNearestCodeword) {
  TrainingScan scan;
  scan.model_index = 1;
  scan.object_center = Eigen::Vector3f(1.0f, 2.0f, 0.5f);
  scan.features.positions = {Eigen::Vector3f(1.0f, 2.0f, 0.0f), Eigen::Vector3f(0.0f, 2.0f, 0.5f)};
  const Eigen::Matrix3f quarter_turn = Eigen::AngleAxisf(static_cast<float>(M_PI / 2), Eigen::Vector3f::UnitZ()).matrix();
  scan.features.lrfs = {Eigen::Matrix3f::Identity(), quarter_turn.transpose()};
  scan.features.descriptors = DescriptorMatrix::Zero(2, 2);
  scan.features.descriptors(0, 1) = 1.0f;  // nearest to codeword 1
  scan.features.descriptors(1, 0) = 1.0f;  // nearest to codeword 0
  const Codebook codebook(DescriptorMatrix::Identity(2, 2));
  const std::vector<TrainingVote> votes = trainingVotes({&scan}, codebook);
  ASSERT_EQ(votes.size(), 2u);
  EXPECT_EQ(votes[0].codeword, 1);
  EXPECT_EQ(votes[0].model, 1);
  EXPECT_TRUE(votes[0].vector.isApprox(Eigen::Vector3f(0.0f, 0.0f, 0.5f)));
  EXPECT_EQ(votes[1].codeword, 0);
  // (1, 0, 0) in the scene is (0, -1, 0) in a frame turned a quarter about z.
  EXPECT_TRUE(votes[1].vector.isApprox(Eigen::Vector3f(0.0f, -1.0f, 0.0f), 1e-6f)) << votes[1].vector.transpose();
}

TEST(TrainingVotes, PackedTableGroupsByCodewordAndLeavesTheExcludedModelOut) {
  const std::vector<TrainingVote> votes{{2, 0, Eigen::Vector3f(1, 0, 0)},
                                        {0, 1, Eigen::Vector3f(2, 0, 0)},
                                        {2, 1, Eigen::Vector3f(3, 0, 0)},
                                        {2, 0, Eigen::Vector3f(4, 0, 0)}};
  const VoteTable all = packVotes(votes, 3);
  EXPECT_EQ(all.offsets, (std::vector<uint32_t>{0, 1, 1, 4}));
  ASSERT_EQ(all.vectors.size(), 4u);
  EXPECT_EQ(all.vectors[0].x(), 2.0f);
  EXPECT_EQ(all.vectors[1].x(), 1.0f);  // codeword 2's votes in their order
  EXPECT_EQ(all.vectors[2].x(), 3.0f);
  EXPECT_EQ(all.vectors[3].x(), 4.0f);
  const VoteTable without_model_1 = packVotes(votes, 3, 1);
  EXPECT_EQ(without_model_1.offsets, (std::vector<uint32_t>{0, 0, 0, 2}));
  ASSERT_EQ(without_model_1.vectors.size(), 2u);
  EXPECT_EQ(without_model_1.vectors[0].x(), 1.0f);
  EXPECT_EQ(without_model_1.vectors[1].x(), 4.0f);
}

}  // namespace
}  // namespace ism
