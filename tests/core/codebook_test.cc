#include "core/codebook/codebook.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/common/cpu_features.h"
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

// Group g's rows are (g, i): the group and the row within it.
DescriptorMatrix group(int g, int size) {
  DescriptorMatrix m(size, 2);
  for (int i = 0; i < size; ++i) m.row(i) << static_cast<float>(g), static_cast<float>(i);
  return m;
}

std::vector<int> perGroup(const DescriptorMatrix& rows, int groups) {
  std::vector<int> count(static_cast<size_t>(groups), 0);
  for (Eigen::Index r = 0; r < rows.rows(); ++r) ++count[static_cast<size_t>(rows(r, 0))];
  return count;
}

TEST(BalancedRows, EachGroupGivesItsShareOrAllItHas) {
  const std::vector<DescriptorMatrix> groups = {group(0, 1000), group(1, 50), group(2, 3), group(3, 400)};
  const DescriptorMatrix rows = balancedRows(groups, 400, 7);
  EXPECT_EQ(perGroup(rows, 4), (std::vector<int>{100, 50, 3, 100}));
  // Drawn without replacement: no row of a group twice.
  std::set<std::pair<float, float>> seen;
  for (Eigen::Index r = 0; r < rows.rows(); ++r) EXPECT_TRUE(seen.insert({rows(r, 0), rows(r, 1)}).second);
  EXPECT_EQ(balancedRows(groups, 400, 7), rows);  // the seed decides the draw
  EXPECT_NE(balancedRows(groups, 400, 8), rows);
}

TEST(BalancedRows, WithoutALimitAsManyOfEachAsTheSmallestHas) {
  const DescriptorMatrix rows = balancedRows({group(0, 30), group(1, 5), group(2, 8)}, 0, 1);
  EXPECT_EQ(perGroup(rows, 3), (std::vector<int>{5, 5, 5}));
}

TEST(BalancedRows, RejectsNoGroupsAndGroupsOfOtherWidths) {
  EXPECT_THROW(balancedRows({}, 100, 1), Error);
  EXPECT_THROW(balancedRows({group(0, 10), DescriptorMatrix::Zero(10, 3)}, 100, 1), Error);
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

// --- The distance kernels against a brute-force double-precision reference -----------------

const DistanceKernel kKernels[] = {DistanceKernel::kBaseline, DistanceKernel::kAvx2, DistanceKernel::kAvx512};

std::string name(DistanceKernel kernel) {
  switch (kernel) {
    case DistanceKernel::kBaseline:
      return "baseline";
    case DistanceKernel::kAvx2:
      return "avx2";
    case DistanceKernel::kAvx512:
      return "avx512";
    default:
      return "auto";
  }
}

// SHOT-like values: non-negative, rows normalised to unit length, so distances lie in [0, 2].
DescriptorMatrix randomUnitRows(int rows, int dim, std::mt19937& rng) {
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  DescriptorMatrix m(rows, dim);
  for (int r = 0; r < rows; ++r) {
    for (int d = 0; d < dim; ++d) m(r, d) = uniform(rng) < 0.3f ? 0.0f : uniform(rng);
    if (m.row(r).norm() > 0) m.row(r).normalize();
  }
  return m;
}

struct Reference {
  Eigen::MatrixXd squared;    // descriptors x codewords, in double
  Eigen::MatrixXd tolerance;  // bound on a float kernel's error for each
};

// Sum of squared differences in double; the float kernels' error is bounded by the sequential
// sum's (dim + 4) ulp on |a|^2 + |b|^2 (cancellation in |a|^2 + |b|^2 - 2ab).
Reference reference(const DescriptorMatrix& a, const DescriptorMatrix& b) {
  Reference ref{Eigen::MatrixXd(a.rows(), b.rows()), Eigen::MatrixXd(a.rows(), b.rows())};
  const double ulp = std::numeric_limits<float>::epsilon();
  for (Eigen::Index i = 0; i < a.rows(); ++i) {
    for (Eigen::Index j = 0; j < b.rows(); ++j) {
      ref.squared(i, j) = (a.row(i).cast<double>() - b.row(j).cast<double>()).squaredNorm();
      ref.tolerance(i, j) = (a.cols() + 4) * ulp *
                            (a.row(i).cast<double>().squaredNorm() + b.row(j).cast<double>().squaredNorm());
    }
  }
  return ref;
}

struct KernelCase {
  int descriptors, codewords, dim;
};

// Sizes around the kernels' tiles (2, 6 and 8 descriptors; 16 and 32 codewords) and groups of
// 24 descriptors, and odd dimensions.
const KernelCase kCases[] = {{37, 19, 352}, {37, 37, 5}, {5, 1, 1}, {61, 50, 13}, {100, 300, 352}, {3, 33, 2}};

TEST(DistanceKernel, MatchesDoubleReference) {
  std::mt19937 rng(11);
  for (const KernelCase& k : kCases) {
    const DescriptorMatrix a = randomUnitRows(k.descriptors, k.dim, rng);
    const DescriptorMatrix b = randomUnitRows(k.codewords, k.dim, rng);
    const Codebook codebook(b);
    const Reference ref = reference(a, b);
    for (DistanceKernel kernel : kKernels) {
      SCOPED_TRACE(name(kernel) + " (runs " + name(Codebook::kernelFor(kernel)) + "), " +
                   std::to_string(k.descriptors) + " x " + std::to_string(k.codewords) + " x " + std::to_string(k.dim));
      const Eigen::MatrixXf d = codebook.squaredDistances(a, kernel);
      ASSERT_EQ(d.rows(), k.descriptors);
      ASSERT_EQ(d.cols(), k.codewords);
      for (int i = 0; i < k.descriptors; ++i) {
        for (int j = 0; j < k.codewords; ++j) {
          ASSERT_GE(d(i, j), 0.0f);
          ASSERT_NEAR(d(i, j), std::max(0.0, ref.squared(i, j)), ref.tolerance(i, j)) << i << ", " << j;
        }
      }
    }
  }
}

TEST(DistanceKernel, AllKernelsAgreeToTheBit) {
  // Every kernel sums the same rounded products in the same order.
  std::mt19937 rng(12);
  for (const KernelCase& k : kCases) {
    const DescriptorMatrix a = randomUnitRows(k.descriptors, k.dim, rng);
    const Codebook codebook(randomUnitRows(k.codewords, k.dim, rng));
    const Eigen::MatrixXf baseline = codebook.squaredDistances(a, DistanceKernel::kBaseline);
    for (DistanceKernel kernel : {DistanceKernel::kAvx2, DistanceKernel::kAvx512}) {
      if (Codebook::kernelFor(kernel) != kernel) {
        std::cout << "[          ] this CPU has no " << name(kernel) << "\n";
        continue;
      }
      EXPECT_EQ(codebook.squaredDistances(a, kernel), baseline)
          << name(kernel) << ", " << k.descriptors << " x " << k.codewords << " x " << k.dim;
    }
  }
}

// The reference activation, written with Eigen's GEMM: -2 A B^T + |a|^2 + |b|^2, then per
// descriptor std::partial_sort, or std::partition and std::sort.
std::vector<Activation> gemmActivation(const DescriptorMatrix& a, const DescriptorMatrix& b, const ActivationParams& p) {
  Eigen::MatrixXf d(a.rows(), b.rows());
  // One thread, the summation order the kernels reproduce: with more, Eigen blocks the product
  // otherwise, and rounds otherwise.
  const int eigen_threads = Eigen::nbThreads();
  Eigen::setNbThreads(1);
  d.noalias() = -2.0f * a * b.transpose();
  Eigen::setNbThreads(eigen_threads);
  d.colwise() += a.rowwise().squaredNorm();
  d.rowwise() += b.rowwise().squaredNorm().transpose();
  d = d.cwiseMax(0.0f);
  std::vector<Activation> out;
  std::vector<int> order(static_cast<size_t>(b.rows()));
  for (Eigen::Index i = 0; i < a.rows(); ++i) {
    const auto closer = [&](int x, int y) { return d(i, x) < d(i, y); };
    std::iota(order.begin(), order.end(), 0);
    auto end = order.begin() + std::min<Eigen::Index>(p.k, b.rows());
    if (p.strategy == ActivationStrategy::kKnn) {
      std::partial_sort(order.begin(), end, order.end(), closer);
    } else {
      end = std::partition(order.begin(), order.end(), [&](int c) { return d(i, c) <= p.cutoff * p.cutoff; });
      std::sort(order.begin(), end, closer);
    }
    for (auto it = order.begin(); it != end; ++it) out.push_back({static_cast<int>(i), *it, std::sqrt(d(i, *it))});
  }
  return out;
}

TEST(DistanceKernel, ActivationsMatchTheGemmActivation) {
  // Same floats but for the GEMM's last few rows (here 296 to 300), which Eigen sums in another
  // order; random data has no near-ties for that to reorder.
  std::mt19937 rng(16);
  const DescriptorMatrix a = randomUnitRows(301, 352, rng);
  DescriptorMatrix b = randomUnitRows(150, 352, rng);
  for (int j = 0; j < b.rows(); ++j) b.row(j) = 0.5f * b.row(j) + 0.5f * a.row(j);
  b.row(7) = b.row(100);  // equal distances, left in the order std::partial_sort leaves them
  const Codebook codebook(b);
  for (const ActivationParams& p : {ActivationParams{ActivationStrategy::kKnn, 1, 0},
                                    ActivationParams{ActivationStrategy::kKnn, 3, 0},
                                    ActivationParams{ActivationStrategy::kKnn, 20, 0},
                                    ActivationParams{ActivationStrategy::kCutoff, 1, 0.9f}}) {
    const std::vector<Activation> expected = gemmActivation(a, b, p);
    for (DistanceKernel kernel : kKernels) {
      SCOPED_TRACE(name(kernel) + (p.strategy == ActivationStrategy::kKnn ? ", k = " + std::to_string(p.k) : ", cutoff"));
      const std::vector<Activation> got = codebook.activate(a, p, kernel);
      ASSERT_EQ(got.size(), expected.size());
      size_t same_float = 0;
      for (size_t n = 0; n < got.size(); ++n) {
        ASSERT_EQ(got[n].keypoint, expected[n].keypoint) << n;
        ASSERT_EQ(got[n].codeword, expected[n].codeword) << "keypoint " << got[n].keypoint;
        EXPECT_NEAR(got[n].distance, expected[n].distance, 2e-6f) << "keypoint " << got[n].keypoint;
        same_float += got[n].distance == expected[n].distance;
      }
      EXPECT_GE(same_float, got.size() * 95 / 100);
    }
  }
}

TEST(DistanceKernel, AutoRunsTheWidestTheCpuHas) {
  EXPECT_EQ(Codebook::kernelFor(DistanceKernel::kBaseline), DistanceKernel::kBaseline);
  const DistanceKernel widest = Codebook::kernelFor(DistanceKernel::kAuto);
  EXPECT_NE(widest, DistanceKernel::kAuto);
  EXPECT_EQ(Codebook::kernelFor(DistanceKernel::kAvx512), widest);
  std::cout << "[          ] widest distance kernel: " << name(widest) << "\n";
}

TEST(DistanceKernel, ThePortablePathCanBeForced) {
  const CpuFeatures all{true, true};
  EXPECT_FALSE(applyPortableOverride(all, "1").avx2);
  EXPECT_FALSE(applyPortableOverride(all, "1").avx512f);
  EXPECT_TRUE(applyPortableOverride(all, nullptr).avx512f);
  EXPECT_TRUE(applyPortableOverride(all, "0").avx2);
  EXPECT_TRUE(applyPortableOverride(all, "").avx2);
  EXPECT_TRUE(applyPortableOverride(all, "yes").avx2);  // not 1 or 0: said on stderr, ignored
  // Under ctest's portable.* runs the variable is set: nothing wider than the baseline may run.
  const char* forced = std::getenv("ISM_PORTABLE_KERNELS");
  if (forced != nullptr && std::string(forced) == "1") {
    EXPECT_FALSE(cpuHasAvx2());
    EXPECT_FALSE(cpuHasAvx512f());
    EXPECT_EQ(Codebook::kernelFor(DistanceKernel::kAuto), DistanceKernel::kBaseline);
  }
}

// Checks activations of `a` against the reference: grouped by keypoint in order, each
// keypoint's codewords nearest first, and a k-NN set or cutoff set that only a near-tie (within
// the kernels' error) could change.
void expectReferenceActivations(const std::vector<Activation>& got, const Reference& ref, const ActivationParams& p) {
  const Eigen::Index n = ref.squared.rows(), m = ref.squared.cols();
  size_t at = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    std::vector<int> codewords;
    for (; at < got.size() && got[at].keypoint == i; ++at) {
      const int c = got[at].codeword;
      ASSERT_TRUE(c >= 0 && c < m) << c;
      EXPECT_NEAR(got[at].distance, std::sqrt(ref.squared(i, c)), 1e-3) << "keypoint " << i << " codeword " << c;
      if (!codewords.empty()) {
        const int previous = codewords.back();
        EXPECT_GE(ref.squared(i, c), ref.squared(i, previous) - ref.tolerance(i, c) - ref.tolerance(i, previous))
            << "keypoint " << i << ": codeword " << c << " after " << previous;
      }
      codewords.push_back(c);
    }
    std::vector<bool> chosen(static_cast<size_t>(m), false);
    for (int c : codewords) chosen[static_cast<size_t>(c)] = true;
    if (p.strategy == ActivationStrategy::kKnn) {
      ASSERT_EQ(codewords.size(), static_cast<size_t>(std::min<Eigen::Index>(p.k, m))) << "keypoint " << i;
      const int last = codewords.back();
      for (int c = 0; c < m; ++c) {
        if (chosen[static_cast<size_t>(c)]) continue;
        EXPECT_GE(ref.squared(i, c), ref.squared(i, last) - ref.tolerance(i, c) - ref.tolerance(i, last))
            << "keypoint " << i << ": codeword " << c << " left out";
      }
    } else {
      const double cutoff = double(p.cutoff) * p.cutoff;
      for (int c = 0; c < m; ++c) {
        if (std::abs(ref.squared(i, c) - cutoff) <= ref.tolerance(i, c)) continue;  // a near-tie either way
        EXPECT_EQ(chosen[static_cast<size_t>(c)], ref.squared(i, c) < cutoff)
            << "keypoint " << i << " codeword " << c << " at " << std::sqrt(ref.squared(i, c));
      }
    }
  }
  EXPECT_EQ(at, got.size()) << "activations out of keypoint order";
}

TEST(DistanceKernel, ActivationsMatchDoubleReference) {
  std::mt19937 rng(13);
  for (const KernelCase& k : kCases) {
    const DescriptorMatrix a = randomUnitRows(k.descriptors, k.dim, rng);
    // Codewords near the descriptors, so that a cutoff of 0.8 takes several of them.
    DescriptorMatrix b = randomUnitRows(k.codewords, k.dim, rng);
    for (int j = 0; j < k.codewords; ++j) b.row(j) = 0.5f * b.row(j) + 0.5f * a.row(j % k.descriptors);
    const Codebook codebook(b);
    const Reference ref = reference(a, b);
    for (const ActivationParams& p : {ActivationParams{ActivationStrategy::kKnn, 1, 0},
                                      ActivationParams{ActivationStrategy::kKnn, 3, 0},
                                      ActivationParams{ActivationStrategy::kKnn, 20, 0},  // partial_sort
                                      ActivationParams{ActivationStrategy::kCutoff, 1, 0.8f}}) {
      for (DistanceKernel kernel : kKernels) {
        SCOPED_TRACE(name(kernel) + (p.strategy == ActivationStrategy::kKnn ? ", k = " + std::to_string(p.k)
                                                                           : ", cutoff") +
                     ", " + std::to_string(k.descriptors) + " x " + std::to_string(k.codewords) + " x " +
                     std::to_string(k.dim));
        const std::vector<Activation> got = codebook.activate(a, p, kernel);
        if (p.strategy == ActivationStrategy::kCutoff) EXPECT_FALSE(got.empty());
        expectReferenceActivations(got, ref, p);
      }
    }
  }
}

TEST(DistanceKernel, EqualDistances) {
  // 40 codewords (two vectors of 16 lanes and a tail of 8 for k = 1's scan): copies of the
  // nearest one in other lanes and in the tail. k = 1 takes the lowest; more take them all first.
  std::mt19937 rng(14);
  const DescriptorMatrix a = randomUnitRows(3, 24, rng);
  DescriptorMatrix b = randomUnitRows(40, 24, rng);
  b.row(21) = b.row(35) = b.row(37) = a.row(0);  // keypoint 0: 21, 35, 37 at distance 0
  b.row(4) = b.row(19) = a.row(1) * 0.9f;        // keypoint 1: 4, 19
  b.row(33) = b.row(38) = a.row(2) * 0.9f;       // keypoint 2: only in the tail
  const Codebook codebook(b);
  const auto first = [](const std::vector<Activation>& v, size_t from, size_t n) {
    std::vector<int> c;
    for (size_t i = from; i < from + n; ++i) c.push_back(v[i].codeword);
    std::sort(c.begin(), c.end());
    return c;
  };
  for (DistanceKernel kernel : kKernels) {
    SCOPED_TRACE(name(kernel));
    const auto one = codebook.activate(a, {ActivationStrategy::kKnn, 1, 0}, kernel);
    ASSERT_EQ(one.size(), 3u);
    EXPECT_EQ(one[0].codeword, 21);
    EXPECT_EQ(one[1].codeword, 4);
    EXPECT_EQ(one[2].codeword, 33);
    const auto three = codebook.activate(a, {ActivationStrategy::kKnn, 3, 0}, kernel);
    ASSERT_EQ(three.size(), 9u);
    EXPECT_EQ(first(three, 0, 3), (std::vector<int>{21, 35, 37}));
    EXPECT_EQ(first(three, 3, 2), (std::vector<int>{4, 19}));
    EXPECT_EQ(first(three, 6, 2), (std::vector<int>{33, 38}));
    const auto many = codebook.activate(a, {ActivationStrategy::kKnn, 30, 0}, kernel);
    ASSERT_EQ(many.size(), 90u);
    EXPECT_EQ(first(many, 0, 3), (std::vector<int>{21, 35, 37}));
    const auto cut = codebook.activate(a, {ActivationStrategy::kCutoff, 1, 0.01f}, kernel);
    ASSERT_EQ(cut.size(), 3u);
    EXPECT_EQ(first(cut, 0, 3), (std::vector<int>{21, 35, 37}));
  }
}

TEST(DistanceKernel, ActivationDoesNotDependOnThreads) {
#ifdef _OPENMP
  std::mt19937 rng(15);
  const DescriptorMatrix a = randomUnitRows(1500, 64, rng);  // three OpenMP blocks
  const Codebook codebook(randomUnitRows(70, 64, rng));
  const int threads = omp_get_max_threads();
  const auto same = [](const std::vector<Activation>& x, const std::vector<Activation>& y) {
    return x.size() == y.size() && std::equal(x.begin(), x.end(), y.begin(), [](const Activation& p, const Activation& q) {
             return p.keypoint == q.keypoint && p.codeword == q.codeword && p.distance == q.distance;
           });
  };
  for (const ActivationParams& p :
       {ActivationParams{ActivationStrategy::kKnn, 2, 0}, ActivationParams{ActivationStrategy::kCutoff, 1, 1.2f}}) {
    omp_set_num_threads(1);
    const auto one = codebook.activate(a, p);
    omp_set_num_threads(3);
    const auto three = codebook.activate(a, p);
    omp_set_num_threads(threads);
    EXPECT_TRUE(same(one, three));
  }
#else
  GTEST_SKIP() << "built without OpenMP";
#endif
}

TEST(DistanceKernel, NoDescriptorsNoActivations) {
  const Codebook codebook(DescriptorMatrix::Random(5, 7));
  EXPECT_TRUE(codebook.activate(DescriptorMatrix(0, 7), {}).empty());
  EXPECT_EQ(codebook.squaredDistances(DescriptorMatrix(0, 7)).rows(), 0);
}

}  // namespace
}  // namespace ism
