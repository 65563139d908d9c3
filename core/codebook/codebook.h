#pragma once
// Codebook: k-means cluster centres of SHOT descriptors, and codeword activation
// (k nearest codewords, or every codeword within a cutoff distance).
#include <cstdint>
#include <vector>

#include "core/common/types.h"

namespace ism {

struct KMeansParams {
  int k = 300;               // the seed: 300 for the global codebook, 150 per category
  int max_iterations = 30;
  float tolerance = 1e-4f;   // stop when the mean distance improves by less (relative)
  // Cluster a random subset when there are more descriptors than this (0 = all).
  int max_samples = 60000;
  uint32_t seed = 42;
};

struct KMeansResult {
  DescriptorMatrix centers;
  double mean_distance = 0;  // mean descriptor-to-centre distance (the seed saw ~0.25)
  int iterations = 0;
};

// k-means++ seeding, Lloyd iterations. k is clamped to the number of distinct samples.
KMeansResult kmeans(const DescriptorMatrix& data, const KMeansParams& params);

// The rows k-means clusters when every group (a category's descriptors) is to weigh the same:
// max_rows / groups.size() rows of each group, drawn at random with `seed`, or all of a group that
// has fewer; with max_rows 0, as many of each as the smallest group has. Pooled rows give the
// categories codewords by how many descriptors their meshes happen to make, and k-means spends its
// centres where descriptors are dense (Jurie and Triggs, "Creating efficient codebooks for visual
// recognition", ICCV 2005). Throws Error(kInvalidInput) for no groups or groups of other widths.
DescriptorMatrix balancedRows(const std::vector<DescriptorMatrix>& groups, int max_rows, uint32_t seed);

enum class ActivationStrategy { kKnn, kCutoff };

struct ActivationParams {
  ActivationStrategy strategy = ActivationStrategy::kKnn;
  int k = 1;             // kKnn: codewords per descriptor
  float cutoff = 0.25f;  // kCutoff: every codeword within this Euclidean distance
};

// Descriptors are unit length and codewords are means of them, no longer than 1: no distance
// between a descriptor and a codeword exceeds this, so a larger cutoff activates nothing more.
constexpr float kMaxDescriptorDistance = 2.0f;

struct Activation {
  int keypoint;
  int codeword;
  float distance;  // Euclidean, descriptor to codeword
};

// Which distance kernel codeword activation runs (x86-64: all three; elsewhere the baseline one).
// kAuto takes the widest one the CPU runs; the others are there so that tests can check each.
// All give the same floats (no fused multiply-adds): each dot product summed in dimension order,
// as Eigen's SSE2 GEMM sums all but its last few rows.
enum class DistanceKernel { kAuto, kBaseline, kAvx2, kAvx512 };

class Codebook {
 public:
  Codebook() = default;
  explicit Codebook(DescriptorMatrix centers);

  int size() const { return static_cast<int>(centers_.rows()); }
  int dim() const { return static_cast<int>(centers_.cols()); }
  const DescriptorMatrix& centers() const { return centers_; }

  // Activations grouped by keypoint in keypoint order, nearest codeword first. Among equal
  // distances k = 1 takes the lowest codeword; more codewords come in the order std::partial_sort
  // (k-NN) or std::sort (cutoff) leaves them. Search is exact and brute force: with a few
  // hundred 352-d codewords no tree beats it.
  std::vector<Activation> activate(const DescriptorMatrix& descriptors, const ActivationParams& params,
                                   DistanceKernel kernel = DistanceKernel::kAuto) const;

  // Squared Euclidean distances of every descriptor to every codeword (descriptors x size()),
  // as activate computes them: |a|^2 + |b|^2 - 2 a.b clamped at zero.
  Eigen::MatrixXf squaredDistances(const DescriptorMatrix& descriptors,
                                   DistanceKernel kernel = DistanceKernel::kAuto) const;

  // The kernel that runs when `kernel` is asked for: kAuto or one the CPU lacks falls back to
  // the widest narrower one it has.
  static DistanceKernel kernelFor(DistanceKernel kernel);

 private:
  DescriptorMatrix centers_;
  Eigen::VectorXf squared_norms_;  // of centers_' rows
  // centers_ in panels of kPanel codewords, each panel dimension-major (dim() x kPanel floats),
  // zero-padded to whole panels; the kernels read it, and squared_norms_ likewise padded.
  std::vector<float> panels_;
  std::vector<float> panel_norms_;
};

}  // namespace ism
