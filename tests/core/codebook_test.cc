#include "core/codebook/codebook.h"

#include <gtest/gtest.h>

#include <random>

#include "core/common/error.h"

namespace ism {
namespace {

DescriptorMatrix rows(std::initializer_list<std::initializer_list<float>> values) {
  DescriptorMatrix m(static_cast<Eigen::Index>(values.size()), static_cast<Eigen::Index>(values.begin()->size()));
  Eigen::Index r = 0;
  for (const auto& row : values) {
    Eigen::Index c = 0;
    for (float v : row) m(r, c++) = v;
    ++r;
  }
  return m;
}

TEST(KMeans, RecoversSeparableBlobs) {
  constexpr int kBlobs = 5, kPerBlob = 60, kDim = 32;
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  DescriptorMatrix truth = DescriptorMatrix::Random(kBlobs, kDim);
  truth.rowwise().normalize();
  DescriptorMatrix data(kBlobs * kPerBlob, kDim);
  for (int i = 0; i < data.rows(); ++i) {
    for (int d = 0; d < kDim; ++d) data(i, d) = truth(i % kBlobs, d) + noise(rng);
  }
  KMeansParams params;
  params.k = kBlobs;
  const KMeansResult result = kmeans(data, params);
  ASSERT_EQ(result.centers.rows(), kBlobs);
  std::vector<bool> matched(kBlobs, false);
  for (int c = 0; c < kBlobs; ++c) {
    Eigen::Index nearest;
    const float distance = (truth.rowwise() - result.centers.row(c)).rowwise().norm().minCoeff(&nearest);
    EXPECT_LT(distance, 0.02f) << "centre " << c;
    EXPECT_FALSE(matched[static_cast<size_t>(nearest)]) << "two centres on blob " << nearest;
    matched[static_cast<size_t>(nearest)] = true;
  }
  // Per-sample distance to its blob centre is ~0.01 * sqrt(32).
  EXPECT_NEAR(result.mean_distance, 0.01 * std::sqrt(32.0), 0.01);
}

TEST(KMeans, ClampsKToDistinctSamples) {
  const DescriptorMatrix data = rows({{1, 0}, {0, 1}, {1, 0}, {0, 1}, {1, 0}, {-1, 0}});
  KMeansParams params;
  params.k = 10;
  const KMeansResult result = kmeans(data, params);
  EXPECT_EQ(result.centers.rows(), 3);
  EXPECT_NEAR(result.mean_distance, 0.0, 1e-6);
}

TEST(KMeans, SubsamplesLargeInputs) {
  DescriptorMatrix data = DescriptorMatrix::Random(500, 8);
  KMeansParams params;
  params.k = 4;
  params.max_samples = 100;
  const KMeansResult result = kmeans(data, params);
  EXPECT_EQ(result.centers.rows(), 4);
  EXPECT_GT(result.iterations, 0);
}

TEST(KMeans, RejectsEmptyInput) {
  EXPECT_THROW(kmeans(DescriptorMatrix(), KMeansParams{}), Error);
}

class ActivationTest : public ::testing::Test {
 protected:
  Codebook codebook{rows({{0, 0}, {1, 0}, {0, 2}})};
  DescriptorMatrix descriptors = rows({{0.9f, 0}, {5, 5}, {0, 1.8f}});
};

TEST_F(ActivationTest, KnnReturnsNearestCodewordsInOrder) {
  const auto a = codebook.activate(descriptors, {ActivationStrategy::kKnn, 2, 0});
  ASSERT_EQ(a.size(), 6u);
  EXPECT_EQ(a[0].keypoint, 0);
  EXPECT_EQ(a[0].codeword, 1);
  EXPECT_NEAR(a[0].distance, 0.1f, 1e-5f);
  EXPECT_EQ(a[1].codeword, 0);
  EXPECT_NEAR(a[1].distance, 0.9f, 1e-5f);
  EXPECT_EQ(a[2].keypoint, 1);
  EXPECT_EQ(a[2].codeword, 2);  // (5,5) is nearest to (0,2)
  EXPECT_EQ(a[4].keypoint, 2);
  EXPECT_EQ(a[4].codeword, 2);
  EXPECT_NEAR(a[4].distance, 0.2f, 1e-5f);
}

TEST_F(ActivationTest, KnnClampsKToCodebookSize) {
  EXPECT_EQ(codebook.activate(descriptors, {ActivationStrategy::kKnn, 10, 0}).size(), 9u);
}

TEST_F(ActivationTest, CutoffReturnsEveryCodewordWithinDistance) {
  const auto a = codebook.activate(descriptors, {ActivationStrategy::kCutoff, 1, 1.0f});
  // Keypoint 0: codewords 1 (0.1) and 0 (0.9); keypoint 1: none; keypoint 2: codeword 2 (0.2).
  ASSERT_EQ(a.size(), 3u);
  EXPECT_EQ(a[0].keypoint, 0);
  EXPECT_EQ(a[0].codeword, 1);
  EXPECT_EQ(a[1].keypoint, 0);
  EXPECT_EQ(a[1].codeword, 0);
  EXPECT_EQ(a[2].keypoint, 2);
  EXPECT_EQ(a[2].codeword, 2);
}

TEST_F(ActivationTest, RejectsDescriptorsOfTheWrongLength) {
  try {
    codebook.activate(DescriptorMatrix::Zero(2, 3), {});
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidInput);
    EXPECT_NE(std::string(e.what()).find("3 values"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ism
