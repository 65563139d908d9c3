#include "core/codebook/codebook.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <string>

#include "core/common/error.h"

namespace ism {
namespace {

// Rows per GEMM block: bounds the distance matrix (block x k floats) and gives OpenMP work units.
constexpr Eigen::Index kBlockRows = 2048;

// Cancellation in |a|^2 + |b|^2 - 2ab leaves ~1e-7 on identical unit vectors; anything below
// this is the same descriptor (distance < 1e-3, far below SHOT's noise).
constexpr float kSameSquaredDistance = 1e-6f;

Eigen::Index blockCount(Eigen::Index rows) { return (rows + kBlockRows - 1) / kBlockRows; }

// Squared distance of every row of `data` to one row `c`, clamped at zero.
void distancesToRow(const DescriptorMatrix& data, const Eigen::VectorXf& norms, const Eigen::RowVectorXf& c,
                    Eigen::VectorXf* out) {
  out->resize(data.rows());
  const float c_norm = c.squaredNorm();
  const Eigen::Index blocks = blockCount(data.rows());
#pragma omp parallel for schedule(static)
  for (Eigen::Index b = 0; b < blocks; ++b) {
    const Eigen::Index begin = b * kBlockRows, len = std::min(kBlockRows, data.rows() - begin);
    out->segment(begin, len).noalias() = data.middleRows(begin, len) * c.transpose();
    for (Eigen::Index i = begin; i < begin + len; ++i) {
      const float d = norms[i] + c_norm - 2.0f * (*out)[i];
      (*out)[i] = d < kSameSquaredDistance ? 0.0f : d;
    }
  }
}

// k-means++: each next centre is drawn with probability proportional to the squared distance
// to the nearest centre already chosen. Stops early when every sample coincides with a centre.
DescriptorMatrix seedCenters(const DescriptorMatrix& data, const Eigen::VectorXf& norms, int k, std::mt19937& rng) {
  const Eigen::Index n = data.rows();
  std::vector<Eigen::Index> chosen{std::uniform_int_distribution<Eigen::Index>(0, n - 1)(rng)};
  Eigen::VectorXf nearest, to_new;
  distancesToRow(data, norms, data.row(chosen[0]), &nearest);
  while (static_cast<int>(chosen.size()) < k) {
    const double total = nearest.cast<double>().sum();
    if (total <= 0) break;
    double target = std::uniform_real_distribution<double>(0, total)(rng);
    Eigen::Index pick = 0;
    for (; pick < n - 1; ++pick) {
      target -= nearest[pick];
      if (target < 0 && nearest[pick] > 0) break;
    }
    if (nearest[pick] <= 0) continue;  // only reachable through rounding at the tail
    chosen.push_back(pick);
    distancesToRow(data, norms, data.row(pick), &to_new);
    nearest = nearest.cwiseMin(to_new);
  }
  DescriptorMatrix centers(static_cast<Eigen::Index>(chosen.size()), data.cols());
  for (size_t i = 0; i < chosen.size(); ++i) centers.row(static_cast<Eigen::Index>(i)) = data.row(chosen[i]);
  return centers;
}

// Squared Euclidean distances of every row of `a` to every row of `b` (a.rows x b.rows), as
// |a|^2 + |b|^2 - 2 a b^T so that the work is one GEMM.
Eigen::MatrixXf squaredDistances(const Eigen::Ref<const DescriptorMatrix>& a, const DescriptorMatrix& b,
                                 const Eigen::VectorXf& b_squared_norms) {
  Eigen::MatrixXf d(a.rows(), b.rows());
  d.noalias() = -2.0f * a * b.transpose();
  d.colwise() += a.rowwise().squaredNorm();
  d.rowwise() += b_squared_norms.transpose();
  return d.cwiseMax(0.0f);
}

}  // namespace

KMeansResult kmeans(const DescriptorMatrix& data, const KMeansParams& params) {
  if (data.rows() == 0 || data.cols() == 0) {
    throw Error(ErrorCode::kInvalidInput, "k-means: no descriptors to cluster");
  }
  if (params.k < 1) {
    throw Error(ErrorCode::kInvalidInput, "k-means: k must be at least 1, got " + std::to_string(params.k));
  }
  std::mt19937 rng(params.seed);
  DescriptorMatrix subset;
  if (params.max_samples > 0 && data.rows() > params.max_samples) {
    std::vector<Eigen::Index> order(static_cast<size_t>(data.rows()));
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    subset.resize(params.max_samples, data.cols());
    for (int i = 0; i < params.max_samples; ++i) subset.row(i) = data.row(order[i]);
  }
  const DescriptorMatrix& x = subset.rows() > 0 ? subset : data;
  const Eigen::Index n = x.rows();
  const Eigen::VectorXf norms = x.rowwise().squaredNorm();

  KMeansResult result;
  result.centers = seedCenters(x, norms, params.k, rng);
  const Eigen::Index k = result.centers.rows();
  std::vector<int> assignment(static_cast<size_t>(n));
  Eigen::VectorXf best(n);
  double previous = std::numeric_limits<double>::infinity();
  for (int iteration = 0; iteration < std::max(1, params.max_iterations); ++iteration) {
    const Eigen::VectorXf center_norms = result.centers.rowwise().squaredNorm();
    const Eigen::Index blocks = blockCount(n);
#pragma omp parallel for schedule(static)
    for (Eigen::Index b = 0; b < blocks; ++b) {
      const Eigen::Index begin = b * kBlockRows, len = std::min(kBlockRows, n - begin);
      const Eigen::MatrixXf d = squaredDistances(x.middleRows(begin, len), result.centers, center_norms);
      for (Eigen::Index i = 0; i < len; ++i) {
        Eigen::Index arg;
        best[begin + i] = d.row(i).minCoeff(&arg);
        assignment[static_cast<size_t>(begin + i)] = static_cast<int>(arg);
      }
    }
    result.mean_distance = best.cwiseSqrt().cast<double>().mean();
    result.iterations = iteration + 1;
    if (iteration > 0 && previous - result.mean_distance <= params.tolerance * previous) break;
    previous = result.mean_distance;

    DescriptorMatrix sums = DescriptorMatrix::Zero(k, x.cols());
    std::vector<int> counts(static_cast<size_t>(k), 0);
    for (Eigen::Index i = 0; i < n; ++i) {
      sums.row(assignment[static_cast<size_t>(i)]) += x.row(i);
      ++counts[static_cast<size_t>(assignment[static_cast<size_t>(i)])];
    }
    for (Eigen::Index c = 0; c < k; ++c) {
      if (counts[static_cast<size_t>(c)] > 0) {
        result.centers.row(c) = sums.row(c) / static_cast<float>(counts[static_cast<size_t>(c)]);
      } else {
        // An empty cluster restarts at the sample worst served by its centre.
        Eigen::Index worst;
        best.maxCoeff(&worst);
        result.centers.row(c) = x.row(worst);
        best[worst] = 0;
      }
    }
  }
  return result;
}

Codebook::Codebook(DescriptorMatrix centers)
    : centers_(std::move(centers)), squared_norms_(centers_.rowwise().squaredNorm()) {}

std::vector<Activation> Codebook::activate(const DescriptorMatrix& descriptors, const ActivationParams& params) const {
  if (size() == 0) throw Error(ErrorCode::kInvalidInput, "codeword activation: the codebook is empty");
  if (descriptors.rows() > 0 && descriptors.cols() != dim()) {
    throw Error(ErrorCode::kInvalidInput, "codeword activation: descriptors have " +
                                              std::to_string(descriptors.cols()) + " values, the codebook " +
                                              std::to_string(dim()));
  }
  const bool knn = params.strategy == ActivationStrategy::kKnn;
  if (knn && params.k < 1) {
    throw Error(ErrorCode::kInvalidInput, "codeword activation: k must be at least 1, got " + std::to_string(params.k));
  }
  if (!knn && !(params.cutoff > 0)) {
    throw Error(ErrorCode::kInvalidInput,
                "codeword activation: cutoff must be positive, got " + std::to_string(params.cutoff));
  }
  const int k = std::min(params.k, size());
  const float cutoff_squared = params.cutoff * params.cutoff;
  const Eigen::Index blocks = blockCount(descriptors.rows());
  std::vector<std::vector<Activation>> per_block(static_cast<size_t>(blocks));
#pragma omp parallel for schedule(dynamic)
  for (Eigen::Index b = 0; b < blocks; ++b) {
    const Eigen::Index begin = b * kBlockRows, len = std::min(kBlockRows, descriptors.rows() - begin);
    const Eigen::MatrixXf d = squaredDistances(descriptors.middleRows(begin, len), centers_, squared_norms_);
    std::vector<int> order(static_cast<size_t>(size()));
    auto& out = per_block[static_cast<size_t>(b)];
    for (Eigen::Index i = 0; i < len; ++i) {
      const auto closer = [&](int a, int c) { return d(i, a) < d(i, c); };
      std::iota(order.begin(), order.end(), 0);
      auto end = order.begin() + k;
      if (knn) {
        std::partial_sort(order.begin(), end, order.end(), closer);
      } else {
        end = std::partition(order.begin(), order.end(), [&](int c) { return d(i, c) <= cutoff_squared; });
        std::sort(order.begin(), end, closer);
      }
      for (auto it = order.begin(); it != end; ++it) {
        out.push_back({static_cast<int>(begin + i), *it, std::sqrt(d(i, *it))});
      }
    }
  }
  std::vector<Activation> activations;
  for (auto& block : per_block) activations.insert(activations.end(), block.begin(), block.end());
  return activations;
}

}  // namespace ism
