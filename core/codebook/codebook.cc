#include "core/codebook/codebook.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <random>
#include <string>

#include "core/common/cpu_features.h"
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

// --- Codeword activation -------------------------------------------------------------------
//
// Activation needs every descriptor's distance to every codeword: 3,473 x 300 dot products of
// 352 floats on tum_desk. The kernels below compute them from raw arrays, in three builds of the
// same source picked at run time: the x86-64 baseline (SSE2), AVX2 and AVX-512. None instantiates
// Eigen: an inline Eigen function compiled for AVX2 could be the copy the linker keeps for every
// caller, and crash a CPU without AVX2.
//
// Each dot product is summed in dimension order, one rounded product at a time, whatever the
// kernel and its tile size, as Eigen's SSE2 GEMM does. So all three kernels give the same floats,
// on any CPU and thread count, and the GEMM's but for its last few rows, which Eigen sums in
// another order. The kernels are built without fused multiply-adds (fp-contract=off) to keep it
// so: FMA would change distances in the last bit, and activation-weighted scores with them.

// Codewords per panel of Codebook::panels_: one AVX-512 register, two AVX2 ones.
constexpr int kPanel = 16;
// Descriptors per OpenMP work unit, and per call of the distance kernel within it.
constexpr Eigen::Index kActivationBlockRows = 512;
constexpr int kGroupRows = 24;

#if defined(__GNUC__)
#define ISM_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define ISM_ALWAYS_INLINE inline
#endif

// Kernels without fused multiply-adds (see above), which GCC and Clang would make where the
// target has FMA: GCC per function, Clang per block (in distanceTile).
#if defined(__GNUC__) && !defined(__clang__)
#define ISM_NO_FMA __attribute__((optimize("fp-contract=off")))
#else
#define ISM_NO_FMA
#endif


// One call of a kernel: up to kGroupRows descriptors against the whole codebook.
struct DistanceArgs {
  const float* rows[kGroupRows];  // the descriptors, dim floats each
  const float* row_norms;         // their squared norms
  int row_count;                  // at most kGroupRows
  int dim;
  const float* panels;       // Codebook::panels_
  const float* panel_norms;  // Codebook::panel_norms_
  int panel_count;
  // kGroupRows rows of panel_count * kPanel squared distances, row-major; the kernel also
  // writes rows past row_count and codewords past the codebook's size, which mean nothing.
  float* out;
};

// GCC's vectors of floats: the baseline kernel takes 4 (SSE2), the AVX2 one 8, the AVX-512 one
// 16. (GCC's vectoriser turns no tile loop written over floats into code that keeps the
// accumulators in registers; these types make it explicit.) Loaded and stored with memcpy,
// from any address.
typedef float Float4 __attribute__((vector_size(16)));
typedef float Float8 __attribute__((vector_size(32)));
typedef float Float16 __attribute__((vector_size(64)));

// (Through a reference: returning an AVX vector from a function that is not compiled for AVX
// is an ABI question, even one that is always inlined.)
template <typename V>
ISM_ALWAYS_INLINE void load(V& to, const float* from) {
  std::memcpy(&to, from, sizeof(V));
}

// Squared distances of R descriptors to C consecutive codewords, the first at `panel` (a panel's
// start or a part-way into it; further panels follow panel_stride floats apart) with squared
// norms from `norms`. Accumulators: R x C / width vectors of codewords, in registers.
template <typename V, int R, int C>
ISM_ALWAYS_INLINE void distanceTile(const float* const* rows, const float* row_norms, int dim, const float* panel,
                                    size_t panel_stride, const float* norms, float* out, int out_stride) {
#if defined(__clang__)
#pragma clang fp contract(off)
#endif
  constexpr int kWidth = sizeof(V) / sizeof(float);
  constexpr int kVectors = C / kWidth;
  static_assert(C % kWidth == 0, "whole vectors of codewords");
  static_assert(C <= kPanel ? kPanel % C == 0 : C % kPanel == 0, "whole panels or even parts of one");
  V acc[R][kVectors];
#pragma GCC unroll 16
  for (int r = 0; r < R; ++r) {
#pragma GCC unroll 16
    for (int j = 0; j < kVectors; ++j) acc[r][j] = V{};
  }
  for (int d = 0; d < dim; ++d) {
    V p[kVectors];
#pragma GCC unroll 16
    for (int j = 0; j < kVectors; ++j) {
      load(p[j], panel + (j * kWidth / kPanel) * panel_stride + d * kPanel + j * kWidth % kPanel);
    }
#pragma GCC unroll 16
    for (int r = 0; r < R; ++r) {
      const float v = rows[r][d];
#pragma GCC unroll 16
      for (int j = 0; j < kVectors; ++j) acc[r][j] += v * p[j];
    }
  }
  // As Eigen evaluated -2 a b^T, then added |a|^2, then |b|^2.
#pragma GCC unroll 16
  for (int j = 0; j < kVectors; ++j) {
    V b;
    load(b, norms + j * kWidth);
#pragma GCC unroll 16
    for (int r = 0; r < R; ++r) {
      const V d = (-2.0f * acc[r][j] + row_norms[r]) + b;
      const V clamped = d < 0.0f ? V{} : d;  // std::max(d, 0.0f), as Eigen's cwiseMax
      std::memcpy(out + r * out_stride + j * kWidth, &clamped, sizeof(V));
    }
  }
}

// Every row of `args` against every codeword, R rows by C codewords at a time (C < kPanel: part
// of a panel; C > kPanel: several panels, the last odd ones by one panel with R x kPanel tiles).
// A last partial group of R rows repeats its last row into the spare rows of args.out.
template <typename V, int R, int C>
ISM_ALWAYS_INLINE void distanceRows(const DistanceArgs& args) {
  static_assert(kGroupRows % R == 0, "args.out has room for whole tiles");
  constexpr int kStep = C < kPanel ? C : kPanel;  // codewords per tile in the odd panels
  const int stride = args.panel_count * kPanel;
  const size_t panel_stride = static_cast<size_t>(args.dim) * kPanel;
  const int wide_end = C > kPanel ? args.panel_count / (C / kPanel) * C : 0;
  for (int r0 = 0; r0 < args.row_count; r0 += R) {
    const float* rows[R];
    float norms[R];
    for (int r = 0; r < R; ++r) {
      const int i = r0 + r < args.row_count ? r0 + r : args.row_count - 1;
      rows[r] = args.rows[i];
      norms[r] = args.row_norms[i];
    }
    float* out = args.out + static_cast<size_t>(r0) * stride;
    for (int c0 = 0; c0 < wide_end; c0 += C) {
      distanceTile<V, R, (C > kPanel ? C : kPanel)>(rows, norms, args.dim, args.panels + c0 / kPanel * panel_stride,
                                                    panel_stride, args.panel_norms + c0, out + c0, stride);
    }
    for (int c0 = wide_end; c0 < stride; c0 += kStep) {
      distanceTile<V, R, kStep>(rows, norms, args.dim, args.panels + c0 / kPanel * panel_stride + c0 % kPanel,
                                panel_stride, args.panel_norms + c0, out + c0, stride);
    }
  }
}


// Tile sizes (measured on tum_desk): as many accumulators as the registers hold beside the
// panel's vectors and the broadcast descriptor value, for enough independent sums in flight.
// SSE2: 2 x 16, 8 accumulators of 4 floats out of 16 registers.
ISM_NO_FMA void distanceRowsBaseline(const DistanceArgs& args) { distanceRows<Float4, 2, 16>(args); }

#if ISM_X86_KERNELS
// AVX2: 6 x 16, 12 accumulators of 8 floats out of 16 registers.
__attribute__((target("avx2"))) ISM_NO_FMA void distanceRowsAvx2(const DistanceArgs& args) {
  distanceRows<Float8, 6, 16>(args);
}
// AVX-512: 8 x 32 (two panels), 16 accumulators of 16 floats out of 32 registers.
__attribute__((target("avx512f"))) ISM_NO_FMA void distanceRowsAvx512(const DistanceArgs& args) {
  distanceRows<Float16, 8, 32>(args);
}
#endif

bool cpuSupports(DistanceKernel kernel) {
  const bool avx2 = cpuHasAvx2(), avx512 = cpuHasAvx512f();
  switch (kernel) {
    case DistanceKernel::kAvx2:
      return avx2;
    case DistanceKernel::kAvx512:
      return avx512;
    default:
      return true;
  }
}

// kAuto: the widest kernel the CPU runs; any other: that one, or the next narrower it runs.
DistanceKernel resolveKernel(DistanceKernel kernel) {
  if (kernel == DistanceKernel::kAuto) kernel = DistanceKernel::kAvx512;
  if (kernel == DistanceKernel::kAvx512 && !cpuSupports(kernel)) kernel = DistanceKernel::kAvx2;
  if (kernel == DistanceKernel::kAvx2 && !cpuSupports(kernel)) kernel = DistanceKernel::kBaseline;
  return kernel;
}

using DistanceRowsFn = void (*)(const DistanceArgs&);

DistanceRowsFn distanceRowsFor(DistanceKernel kernel) {
  switch (resolveKernel(kernel)) {
#if ISM_X86_KERNELS
    case DistanceKernel::kAvx512:
      return distanceRowsAvx512;
    case DistanceKernel::kAvx2:
      return distanceRowsAvx2;
#endif
    default:
      return distanceRowsBaseline;
  }
}

// The first c with the least row[c] (c = 0 when row[0] is NaN), as a scan that keeps the first
// of equal minima; in kLanes interleaved running minima with their codewords, which are SSE2
// vectors (GCC does not vectorise the scalar loop, a float select beside an int one).
int nearestCodeword(const float* row, int codewords) {
  typedef int Int4 __attribute__((vector_size(16)));
  constexpr int kVectors = 4, kLanes = 4 * kVectors;
  const int whole = codewords / kLanes * kLanes;
  int best = 0;
  if (whole > 0 && !std::isnan(row[0])) {
    Float4 least[kVectors];
    Int4 at[kVectors];
    for (int j = 0; j < kVectors; ++j) {
      load(least[j], row + 4 * j);
      at[j] = Int4{0, 1, 2, 3} + 4 * j;
    }
    for (int c = kLanes; c < whole; c += kLanes) {
      for (int j = 0; j < kVectors; ++j) {
        Float4 v;
        load(v, row + c + 4 * j);
        const Int4 less = v < least[j];
        least[j] = less ? v : least[j];
        at[j] = less ? Int4{0, 1, 2, 3} + (c + 4 * j) : at[j];
      }
    }
    best = at[0][0];
    for (int j = 0; j < kVectors; ++j) {
      for (int l = 0; l < 4; ++l) {
        if (least[j][l] < row[best] || (least[j][l] == row[best] && at[j][l] < best)) best = at[j][l];
      }
    }
  }
  for (int c = whole > 0 && !std::isnan(row[0]) ? whole : 1; c < codewords; ++c) {
    if (row[c] < row[best]) best = c;
  }
  return best;
}

// Appends row i's activations: its k nearest codewords, or those within the cutoff, nearest
// first. `row` holds its squared distances. The selection is std::partial_sort or
// std::partition and std::sort over the codewords in order, so that equal distances come out in
// the order Codebook::activate documents; k = 1 is a scan for the first least distance, which is
// what std::partial_sort picks.
void selectCodewords(const float* row, int codewords, int keypoint, bool knn, int k, float cutoff_squared,
                     std::vector<int>* order, std::vector<Activation>* out) {
  if (knn && k == 1) {
    const int best = nearestCodeword(row, codewords);
    out->push_back({keypoint, best, std::sqrt(row[best])});
    return;
  }
  const auto closer = [row](int a, int b) { return row[a] < row[b]; };
  order->resize(static_cast<size_t>(codewords));
  std::iota(order->begin(), order->end(), 0);
  auto end = order->begin() + k;
  if (knn) {
    std::partial_sort(order->begin(), end, order->end(), closer);
  } else {
    end = std::partition(order->begin(), order->end(), [&](int c) { return row[c] <= cutoff_squared; });
    std::sort(order->begin(), end, closer);
  }
  for (auto it = order->begin(); it != end; ++it) out->push_back({keypoint, *it, std::sqrt(row[*it])});
}

// n rows of `from` drawn without replacement (a shuffle of all its rows' order, then the first n)
// into `to`, from row `at` on.
void copyRandomRows(const DescriptorMatrix& from, Eigen::Index n, std::mt19937& rng, DescriptorMatrix& to, Eigen::Index at) {
  std::vector<Eigen::Index> order(static_cast<size_t>(from.rows()));
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  for (Eigen::Index i = 0; i < n; ++i) to.row(at + i) = from.row(order[static_cast<size_t>(i)]);
}

}  // namespace

DescriptorMatrix balancedRows(const std::vector<DescriptorMatrix>& groups, int max_rows, uint32_t seed) {
  if (groups.empty()) throw Error(ErrorCode::kInvalidInput, "balanced rows: no groups");
  Eigen::Index share = std::numeric_limits<Eigen::Index>::max();
  if (max_rows > 0) {
    share = std::max<Eigen::Index>(1, max_rows / static_cast<Eigen::Index>(groups.size()));
  } else {
    for (const auto& g : groups) share = std::min(share, g.rows());
  }
  Eigen::Index rows = 0;
  for (const auto& g : groups) {
    if (g.cols() != groups.front().cols()) throw Error(ErrorCode::kInvalidInput, "balanced rows: groups of other widths");
    rows += std::min(share, g.rows());
  }
  std::mt19937 rng(seed);
  DescriptorMatrix out(rows, groups.front().cols());
  Eigen::Index at = 0;
  for (const auto& g : groups) {
    if (g.rows() <= share) {
      out.middleRows(at, g.rows()) = g;
      at += g.rows();
      continue;
    }
    copyRandomRows(g, share, rng, out, at);
    at += share;
  }
  return out;
}

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
    subset.resize(params.max_samples, data.cols());
    copyRandomRows(data, params.max_samples, rng, subset, 0);
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
    : centers_(std::move(centers)), squared_norms_(centers_.rowwise().squaredNorm()) {
  const Eigen::Index panels = (centers_.rows() + kPanel - 1) / kPanel;
  panels_.assign(static_cast<size_t>(panels * centers_.cols() * kPanel), 0.0f);
  panel_norms_.assign(static_cast<size_t>(panels * kPanel), 0.0f);
  for (Eigen::Index c = 0; c < centers_.rows(); ++c) {
    const Eigen::Index panel = c / kPanel, lane = c % kPanel;
    for (Eigen::Index d = 0; d < centers_.cols(); ++d) {
      panels_[static_cast<size_t>((panel * centers_.cols() + d) * kPanel + lane)] = centers_(c, d);
    }
    panel_norms_[static_cast<size_t>(c)] = squared_norms_[c];
  }
}

DistanceKernel Codebook::kernelFor(DistanceKernel kernel) { return resolveKernel(kernel); }

namespace {

// Calls `fn(i, row)` for every descriptor i of [begin, begin + len) with the squared distances of
// it to every codeword (row[0..size)).
template <typename Fn>
void forEachDistanceRow(const DescriptorMatrix& descriptors, Eigen::Index begin, Eigen::Index len,
                        const float* panels, const std::vector<float>& panel_norms, int dim,
                        DistanceKernel kernel, Fn&& fn) {
  const Eigen::VectorXf norms = descriptors.middleRows(begin, len).rowwise().squaredNorm();
  const int panel_count = static_cast<int>(panel_norms.size() / kPanel);
  const int stride = panel_count * kPanel;
  std::vector<float> out(static_cast<size_t>(kGroupRows * stride));
  const DistanceRowsFn distance_rows = distanceRowsFor(kernel);
  DistanceArgs args{};
  args.dim = dim;
  args.panels = panels;
  args.panel_norms = panel_norms.data();
  args.panel_count = panel_count;
  args.out = out.data();
  for (Eigen::Index g = 0; g < len; g += kGroupRows) {
    args.row_count = static_cast<int>(std::min<Eigen::Index>(kGroupRows, len - g));
    for (int r = 0; r < args.row_count; ++r) args.rows[r] = descriptors.data() + (begin + g + r) * dim;
    args.row_norms = norms.data() + g;
    distance_rows(args);
    for (int r = 0; r < args.row_count; ++r) fn(begin + g + r, out.data() + static_cast<size_t>(r) * stride);
  }
}

}  // namespace

Eigen::MatrixXf Codebook::squaredDistances(const DescriptorMatrix& descriptors, DistanceKernel kernel) const {
  if (descriptors.rows() > 0 && descriptors.cols() != dim()) {
    throw Error(ErrorCode::kInvalidInput, "codeword distances: descriptors have " +
                                              std::to_string(descriptors.cols()) + " values, the codebook " +
                                              std::to_string(dim()));
  }
  Eigen::MatrixXf d(descriptors.rows(), size());
  if (size() == 0) return d;
  forEachDistanceRow(descriptors, 0, descriptors.rows(), panels_.data(), panel_norms_, dim(), kernel,
                     [&](Eigen::Index i, const float* row) {
                       for (int c = 0; c < size(); ++c) d(i, c) = row[c];
                     });
  return d;
}

std::vector<Activation> Codebook::activate(const DescriptorMatrix& descriptors, const ActivationParams& params,
                                           DistanceKernel kernel) const {
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
  const Eigen::Index rows = descriptors.rows();
  const Eigen::Index blocks = (rows + kActivationBlockRows - 1) / kActivationBlockRows;
  std::vector<std::vector<Activation>> per_block(static_cast<size_t>(blocks));
#pragma omp parallel for schedule(dynamic)
  for (Eigen::Index b = 0; b < blocks; ++b) {
    const Eigen::Index begin = b * kActivationBlockRows, len = std::min(kActivationBlockRows, rows - begin);
    auto& out = per_block[static_cast<size_t>(b)];
    if (knn) out.reserve(static_cast<size_t>(len * k));
    std::vector<int> order;
    order.reserve(static_cast<size_t>(size()));
    forEachDistanceRow(descriptors, begin, len, panels_.data(), panel_norms_, dim(), kernel,
                       [&](Eigen::Index i, const float* row) {
                         selectCodewords(row, size(), static_cast<int>(i), knn, k, cutoff_squared, &order, &out);
                       });
  }
  std::vector<Activation> activations;
  size_t total = 0;
  for (const auto& block : per_block) total += block.size();
  activations.reserve(total);
  for (auto& block : per_block) activations.insert(activations.end(), block.begin(), block.end());
  return activations;
}

}  // namespace ism
