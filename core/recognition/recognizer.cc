#include "core/recognition/recognizer.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iterator>
#include <limits>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/common/error.h"
#include "core/common/hash.h"

namespace ism {
namespace {

const VoteTable& votesOf(const CategoryModel& category, CodebookType type) {
  return type == CodebookType::kGlobal ? category.global_votes : category.own_votes;
}

// The cube of edge `bin_size` centred at `center`; scoreAt and findPeaks must agree on it.
bool insideCube(const Eigen::Vector3f& p, const Eigen::Vector3f& center, float half_edge) {
  return ((p - center).cwiseAbs().array() <= half_edge).all();
}

// Hough bins are addressed by their integer coordinates packed into 63 bits (21 bits each, so
// ~100 km of range at 10 cm bins); the top bit stays clear and marks empty hash slots. Key
// order is the lexicographic order of the coordinates.
using BinKey = uint64_t;
constexpr int64_t kBinOffset = int64_t{1} << 20;
constexpr BinKey kBinMask = (BinKey{1} << 21) - 1;
constexpr BinKey kEmptyKey = ~BinKey{0};

BinKey keyOf(const Eigen::Vector3i& b) {
  return (static_cast<BinKey>(b.x() + kBinOffset) & kBinMask) << 42 |
         (static_cast<BinKey>(b.y() + kBinOffset) & kBinMask) << 21 | (static_cast<BinKey>(b.z() + kBinOffset) & kBinMask);
}

Eigen::Vector3i binOfKey(BinKey key) {
  const auto coordinate = [&](int shift) { return static_cast<int>(static_cast<int64_t>((key >> shift) & kBinMask) - kBinOffset); };
  return {coordinate(42), coordinate(21), coordinate(0)};
}

// A bin and its 26 neighbours: a cube of edge bin_size centred anywhere in the bin lies inside.
const std::array<Eigen::Vector3i, 27>& neighbourhood() {
  static const std::array<Eigen::Vector3i, 27> offsets = [] {
    std::array<Eigen::Vector3i, 27> o;
    for (int i = 0; i < 27; ++i) o[static_cast<size_t>(i)] = Eigen::Vector3i(i / 9 - 1, i / 3 % 3 - 1, i % 3 - 1);
    return o;
  }();
  return offsets;
}

// Open addressing with linear probing in one flat array: a vote costs one probe into one cache
// line instead of std::unordered_map's node per bin.
template <typename Value>
class BinMap {
 public:
  struct Slot {
    BinKey key = kEmptyKey;
    Value value{};
  };

  Value& operator[](BinKey key) {
    if ((size_ + 1) * 2 > slots_.size()) grow();
    for (size_t i = home(key);; i = (i + 1) & (slots_.size() - 1)) {
      Slot& slot = slots_[i];
      if (slot.key == key) return slot.value;
      if (slot.key == kEmptyKey) {
        slot.key = key;
        ++size_;
        return slot.value;
      }
    }
  }

  const Value* find(BinKey key) const {
    if (slots_.empty()) return nullptr;
    for (size_t i = home(key);; i = (i + 1) & (slots_.size() - 1)) {
      const Slot& slot = slots_[i];
      if (slot.key == key) return &slot.value;
      if (slot.key == kEmptyKey) return nullptr;
    }
  }

  size_t size() const { return size_; }
  const std::vector<Slot>& slots() const { return slots_; }  // empty ones have kEmptyKey

 private:
  // The top bits of a full mix (core/common/hash.h).
  size_t home(BinKey key) const { return static_cast<size_t>(mix64(key) >> shift_); }

  void grow() {
    std::vector<Slot> old = std::move(slots_);
    slots_.assign(std::max<size_t>(64, old.size() * 2), Slot{});
    shift_ = 64 - static_cast<int>(std::log2(static_cast<double>(slots_.size())));
    size_ = 0;
    for (const Slot& slot : old) {
      if (slot.key != kEmptyKey) (*this)[slot.key] = slot.value;
    }
  }

  std::vector<Slot> slots_;
  int shift_ = 64;
  size_t size_ = 0;
};

int maxThreads() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

// Splits [0, n) into one contiguous range per thread and lets each fill its own accumulator.
// Merging the accumulators in range order makes results independent of thread scheduling.
template <typename Accumulator, typename Body>
std::vector<Accumulator> perThreadRanges(size_t n, size_t min_per_thread, Body&& body) {
  const int threads = static_cast<int>(std::clamp<size_t>(n / min_per_thread, 1, static_cast<size_t>(maxThreads())));
  std::vector<Accumulator> parts(static_cast<size_t>(threads));
#pragma omp parallel for schedule(static, 1) num_threads(threads)
  for (int t = 0; t < threads; ++t) {
    body(parts[static_cast<size_t>(t)], n * static_cast<size_t>(t) / static_cast<size_t>(threads),
         n * static_cast<size_t>(t + 1) / static_cast<size_t>(threads));
  }
  return parts;
}

// Below this many keypoints per thread, starting threads costs more than the votes.
constexpr size_t kKeypointsPerThread = 512;

// Exact floor for |v| < 2^31 without a libm call, so that the loops over a chunk vectorise.
inline int32_t floorToInt(float v) {
  const auto t = static_cast<int32_t>(v);
  return t - static_cast<int32_t>(static_cast<float>(t) > v);
}

// Votes are produced in chunks of positions in structure-of-arrays layout: the rotation and the
// bin coordinates then run as vector instructions.
constexpr uint32_t kChunk = 256;

struct VoteChunk {
  uint32_t size = 0;
  float weight = 0;
  alignas(16) float x[kChunk], y[kChunk], z[kChunk];
  Eigen::Vector3f position(uint32_t j) const { return {x[j], y[j], z[j]}; }
};

// Bin coordinates of a chunk's votes: floor(p * (1 / bin_size)), the definition of a vote's bin.
struct ChunkBins {
  alignas(16) int32_t x[kChunk], y[kChunk], z[kChunk];
  ChunkBins(const VoteChunk& chunk, float inverse_bin_size) {
    for (uint32_t j = 0; j < chunk.size; ++j) {
      x[j] = floorToInt(chunk.x[j] * inverse_bin_size);
      y[j] = floorToInt(chunk.y[j] * inverse_bin_size);
      z[j] = floorToInt(chunk.z[j] * inverse_bin_size);
    }
  }
  BinKey key(uint32_t j) const { return keyOf(Eigen::Vector3i(x[j], y[j], z[j])); }
};

// One category's votes, keypoint by keypoint: the activations grouped per keypoint so that
// keypoints can be split between threads and each keypoint's M (activated codewords) is known.
class VoteCaster {
 public:
  VoteCaster(const Model& model, int category_index, const Features& features,
             const std::vector<Activation>& activations, const Strategy& strategy)
      : category_(model.categories.at(static_cast<size_t>(category_index))),
        table_(votesOf(category_, strategy.codebook)),
        features_(features),
        weighting_(strategy.weighting),
        offsets_(features.size() + 1, 0) {
    if (table_.empty()) return;
    const int codewords = static_cast<int>(table_.offsets.size()) - 1;
    for (const auto& a : activations) {
      if (a.keypoint < 0 || static_cast<size_t>(a.keypoint) >= features.size() || a.codeword < 0 ||
          a.codeword >= codewords) {
        throw Error(ErrorCode::kInvalidInput, "castVotes: activation (keypoint " + std::to_string(a.keypoint) +
                                                  ", codeword " + std::to_string(a.codeword) + ") is out of range for " +
                                                  std::to_string(features.size()) + " keypoints and " +
                                                  std::to_string(codewords) + " codewords of category '" +
                                                  category_.name + "'");
      }
      ++offsets_[static_cast<size_t>(a.keypoint) + 1];
      votes_ += table_.occurrences(a.codeword);
    }
    for (size_t k = 0; k < features.size(); ++k) offsets_[k + 1] += offsets_[k];
    by_keypoint_.resize(activations.size());
    std::vector<uint32_t> cursor(offsets_.begin(), offsets_.end() - 1);
    for (const auto& a : activations) by_keypoint_[cursor[static_cast<size_t>(a.keypoint)]++] = a;
  }

  const CategoryModel& category() const { return category_; }
  const Features& features() const { return features_; }
  size_t keypoints() const { return features_.size(); }
  size_t votes() const { return votes_; }

  // Calls f(chunk) for the votes of keypoint k, chunk by chunk.
  template <typename F>
  void forEachChunk(size_t k, VoteChunk& chunk, F&& f) const {
    const uint32_t begin = offsets_[k], end = offsets_[k + 1];
    if (begin == end) return;
    const Eigen::Matrix3f& r = features_.lrfs[k];  // scene -> LRF; votes go back with its transpose
    const Eigen::Vector3f& o = features_.positions[k];
    const float activated = static_cast<float>(end - begin);
    for (uint32_t i = begin; i < end; ++i) {
      const Activation& a = by_keypoint_[i];
      const uint32_t first = table_.offsets[static_cast<size_t>(a.codeword)];
      const uint32_t last = table_.offsets[static_cast<size_t>(a.codeword) + 1];
      if (first == last) continue;
      chunk.weight = 1.0f;
      if (weighting_ != VoteWeighting::kCategorization) {
        chunk.weight = 1.0f / (activated * static_cast<float>(last - first));
        if (weighting_ == VoteWeighting::kActivation) chunk.weight *= 1.0f - a.distance / 2.0f;
      }
      for (uint32_t start = first; start < last; start += kChunk) {
        chunk.size = std::min(kChunk, last - start);
        const Eigen::Vector3f* v = table_.vectors.data() + start;
        for (uint32_t j = 0; j < chunk.size; ++j) {
          chunk.x[j] = o.x() + (r(0, 0) * v[j].x() + r(1, 0) * v[j].y() + r(2, 0) * v[j].z());
          chunk.y[j] = o.y() + (r(0, 1) * v[j].x() + r(1, 1) * v[j].y() + r(2, 1) * v[j].z());
          chunk.z[j] = o.z() + (r(0, 2) * v[j].x() + r(1, 2) * v[j].y() + r(2, 2) * v[j].z());
        }
        f(static_cast<const VoteChunk&>(chunk));
      }
    }
  }

 private:
  const CategoryModel& category_;
  const VoteTable& table_;
  const Features& features_;
  VoteWeighting weighting_;
  std::vector<uint32_t> offsets_;  // activations of keypoint k: by_keypoint_[offsets_[k] .. offsets_[k+1])
  std::vector<Activation> by_keypoint_;
  size_t votes_ = 0;
};

// What a Hough bin keeps of its votes: enough for the peak test and the peak's centre.
struct BinSum {
  double weight = 0;
  double x = 0, y = 0, z = 0;  // weighted position sum
};

struct Range {
  uint32_t begin = 0, end = 0;
};

}  // namespace

struct HoughSpace::Impl {
  VoteCaster caster;
  BinMap<BinSum> bins;
};

HoughSpace::HoughSpace(const Model& model, int category_index, const Features& features,
                       const std::vector<Activation>& activations, const Strategy& strategy)
    : impl_(new Impl{VoteCaster(model, category_index, features, activations, strategy), {}}) {
  const VoteCaster& caster = impl_->caster;
  const float inverse_bin_size = 1.0f / caster.category().bin_size;
  auto parts = perThreadRanges<BinMap<BinSum>>(caster.keypoints(), kKeypointsPerThread,
                                               [&](BinMap<BinSum>& bins, size_t begin, size_t end) {
    VoteChunk chunk;
    for (size_t k = begin; k < end; ++k) {
      caster.forEachChunk(k, chunk, [&](const VoteChunk& votes) {
        const ChunkBins in(votes, inverse_bin_size);
        const double w = votes.weight;
        for (uint32_t j = 0; j < votes.size; ++j) {
          BinSum& sum = bins[in.key(j)];
          sum.weight += w;
          sum.x += w * votes.x[j];
          sum.y += w * votes.y[j];
          sum.z += w * votes.z[j];
        }
      });
    }
  });
  impl_->bins = std::move(parts[0]);
  for (size_t t = 1; t < parts.size(); ++t) {
    for (const auto& slot : parts[t].slots()) {
      if (slot.key == kEmptyKey) continue;
      BinSum& sum = impl_->bins[slot.key];
      sum.weight += slot.value.weight;
      sum.x += slot.value.x;
      sum.y += slot.value.y;
      sum.z += slot.value.z;
    }
    parts[t] = {};
  }
}

HoughSpace::~HoughSpace() = default;

size_t HoughSpace::votes() const { return impl_->caster.votes(); }
size_t HoughSpace::bins() const { return impl_->bins.size(); }

std::vector<Hypothesis> HoughSpace::findPeaks(float threshold) const {
  const VoteCaster& caster = impl_->caster;
  const BinMap<BinSum>& bins = impl_->bins;
  const CategoryModel& category = caster.category();
  const float bin_size = category.bin_size, half_edge = bin_size / 2;

  // Local maxima whose 27 bins together could exceed the threshold (the cube around a centre
  // inside the bin lies within them): the only bins worth scoring.
  struct Candidate {
    BinKey key;
    Eigen::Vector3f center;
  };
  const auto& slots = bins.slots();
  auto found = perThreadRanges<std::vector<Candidate>>(slots.size(), 4096, [&](std::vector<Candidate>& out, size_t begin,
                                                                               size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const auto& slot = slots[i];
      if (slot.key == kEmptyKey || !(slot.value.weight > 0)) continue;
      const Eigen::Vector3i bin = binOfKey(slot.key);
      const double weight = slot.value.weight;
      double bound = 0;
      bool maximum = true;
      for (const Eigen::Vector3i& d : neighbourhood()) {
        const BinKey key = keyOf(bin + d);
        const BinSum* n = bins.find(key);
        if (n == nullptr) continue;
        if (n->weight > weight || (n->weight == weight && key < slot.key)) {
          maximum = false;
          break;
        }
        bound += n->weight;
      }
      if (!maximum || !(bound > threshold)) continue;
      const Eigen::Vector3d center = Eigen::Vector3d(slot.value.x, slot.value.y, slot.value.z) / weight;
      out.push_back({slot.key, center.cast<float>()});
    }
  });
  std::vector<Candidate> candidates;
  for (auto& part : found) std::move(part.begin(), part.end(), std::back_inserter(candidates));
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) { return a.key < b.key; });
  if (candidates.empty()) return {};

  // Each bin next to a candidate -> the candidates it neighbours (up to 8: maxima are not adjacent).
  std::vector<std::pair<BinKey, uint32_t>> near;
  near.reserve(candidates.size() * 27);
  for (size_t c = 0; c < candidates.size(); ++c) {
    const Eigen::Vector3i bin = binOfKey(candidates[c].key);
    for (const Eigen::Vector3i& d : neighbourhood()) near.emplace_back(keyOf(bin + d), static_cast<uint32_t>(c));
  }
  std::sort(near.begin(), near.end());
  BinMap<Range> neighbours_of;
  // Most votes land far from every candidate. A 32 KB bitmap of the bins near candidates (one
  // bit per Fibonacci hash of the key) stays in L1 and turns those votes away before the
  // full-mix hash probe into neighbours_of, which misses the cache on large scenes.
  constexpr int kFilterBits = 18;
  std::vector<uint64_t> near_filter(size_t{1} << (kFilterBits - 6), 0);
  const auto filterBit = [](BinKey key) { return (key * 0x9E3779B97F4A7C15ull) >> (64 - kFilterBits); };
  for (uint32_t i = 0; i < near.size(); ++i) {
    Range& range = neighbours_of[near[i].first];
    if (range.end == 0) range.begin = i;
    range.end = i + 1;
    const uint64_t bit = filterBit(near[i].first);
    near_filter[bit >> 6] |= uint64_t{1} << (bit & 63);
  }

  // Cast the votes again and look only at those next to a candidate. (Skipping codewords whose
  // votes are all too short to reach a candidate saved nothing measurable in room scans: votes
  // reach across the objects, candidates are all over the room.)
  const float inverse_bin_size = 1.0f / bin_size;
  struct Support {
    std::vector<double> score;
    std::vector<std::vector<int>> keypoints;  // ascending, each once
  };
  auto parts = perThreadRanges<Support>(caster.keypoints(), kKeypointsPerThread, [&](Support& s, size_t begin, size_t end) {
    s.score.assign(candidates.size(), 0.0);
    s.keypoints.resize(candidates.size());
    VoteChunk chunk;
    for (size_t k = begin; k < end; ++k) {
      caster.forEachChunk(k, chunk, [&](const VoteChunk& votes) {
        const ChunkBins in(votes, inverse_bin_size);
        for (uint32_t j = 0; j < votes.size; ++j) {
          const BinKey key = in.key(j);
          const uint64_t bit = filterBit(key);
          if (!(near_filter[bit >> 6] >> (bit & 63) & 1)) continue;
          const Range* range = neighbours_of.find(key);
          if (range == nullptr) continue;
          const Eigen::Vector3f p = votes.position(j);
          for (uint32_t i = range->begin; i < range->end; ++i) {
            const uint32_t c = near[i].second;
            if (!insideCube(p, candidates[c].center, half_edge)) continue;
            s.score[c] += votes.weight;
            auto& keypoints = s.keypoints[c];
            if (keypoints.empty() || keypoints.back() != static_cast<int>(k)) keypoints.push_back(static_cast<int>(k));
          }
        }
      });
    }
  });

  const Features& features = caster.features();
  std::vector<Hypothesis> peaks;
  for (size_t c = 0; c < candidates.size(); ++c) {
    double score = 0;
    for (const auto& part : parts) score += part.score[c];
    Hypothesis h;
    h.score = static_cast<float>(score);
    if (!(h.score > threshold)) continue;
    h.category = category.name;
    h.threshold = threshold;
    h.center = candidates[c].center;
    for (const auto& part : parts) {  // ranges in keypoint order: concatenated, still each once
      for (int k : part.keypoints[c]) h.support_keypoints.push_back(features.positions[static_cast<size_t>(k)]);
    }
    h.support = static_cast<int>(h.support_keypoints.size());
    for (const auto& p : h.support_keypoints) h.support_centroid += p;
    h.support_centroid /= static_cast<float>(h.support);
    h.box = fitOrientedBox(h.support_keypoints);
    h.passed_selection = passesBoxSelection(h.box, category.box);
    peaks.push_back(std::move(h));
  }
  std::stable_sort(peaks.begin(), peaks.end(), [](const Hypothesis& a, const Hypothesis& b) { return a.score > b.score; });
  std::vector<Hypothesis> kept;
  for (auto& p : peaks) {
    const bool duplicate = std::any_of(kept.begin(), kept.end(), [&](const Hypothesis& k) {
      return (k.center - p.center).norm() < bin_size;
    });
    if (!duplicate) kept.push_back(std::move(p));
  }
  return kept;
}

std::vector<Vote> castVotes(const Model& model, int category_index, const Features& features,
                            const std::vector<Activation>& activations, const Strategy& strategy) {
  const VoteCaster caster(model, category_index, features, activations, strategy);
  std::vector<Vote> votes;
  votes.reserve(caster.votes());
  VoteChunk chunk;
  for (size_t k = 0; k < caster.keypoints(); ++k) {
    caster.forEachChunk(k, chunk, [&](const VoteChunk& c) {
      for (uint32_t j = 0; j < c.size; ++j) votes.push_back({c.position(j), c.weight, static_cast<int>(k), category_index});
    });
  }
  return votes;
}

float scoreAt(const std::vector<Vote>& votes, const Eigen::Vector3f& center, float bin_size) {
  float score = 0;
  for (const auto& v : votes) {
    if (insideCube(v.position, center, bin_size / 2)) score += v.weight;
  }
  return score;
}

OrientedBox fitOrientedBox(const std::vector<Eigen::Vector3f>& points) {
  OrientedBox box;
  if (points.empty()) return box;
  Eigen::Vector3f mean = Eigen::Vector3f::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<float>(points.size());
  Eigen::Matrix3f covariance = Eigen::Matrix3f::Zero();
  for (const auto& p : points) covariance += (p - mean) * (p - mean).transpose();
  Eigen::Matrix3f axes = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f>(covariance).eigenvectors();
  if (axes.determinant() < 0) axes.col(0) = -axes.col(0);  // keep a proper rotation
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max()), hi = -lo;
  for (const auto& p : points) {
    const Eigen::Vector3f local = axes.transpose() * (p - mean);
    lo = lo.cwiseMin(local);
    hi = hi.cwiseMax(local);
  }
  box.size = hi - lo;
  box.center = mean + axes * ((lo + hi) / 2);
  box.rotation = Eigen::Quaternionf(axes).normalized();
  return box;
}

bool passesBoxSelection(const OrientedBox& box, const BoxStats& stats) {
  const float volume = box.volume();
  return volume >= stats.min_volume && volume <= stats.max_volume && box.longestEdge() <= stats.max_edge;
}

namespace {

// The categories to search and their thresholds, checked before any work is done.
struct Plan {
  std::vector<int> categories;  // indices into Model::categories
  std::vector<float> thresholds;
};

Plan planRecognition(const Model& model, const RecognitionOptions& options) {
  const Strategy& strategy = options.strategy;
  Plan plan;
  if (options.categories.empty()) {
    for (size_t i = 0; i < model.categories.size(); ++i) plan.categories.push_back(static_cast<int>(i));
  }
  for (const auto& name : options.categories) {
    const CategoryModel* c = model.find(name);
    if (c == nullptr) {
      std::string known;
      for (const auto& k : model.categories) known += (known.empty() ? "" : ", ") + k.name;
      throw Error(ErrorCode::kNotFound, "category '" + name + "' is not in the model (it has: " + known + ")");
    }
    plan.categories.push_back(static_cast<int>(c - model.categories.data()));
  }
  if (!model.has(strategy.codebook)) {
    throw Error(ErrorCode::kInvalidInput,
                std::string("the model was trained without the ") + toString(strategy.codebook) + " codebook");
  }
  for (int ci : plan.categories) {
    const CategoryModel& c = model.categories[static_cast<size_t>(ci)];
    if (options.min_score) {
      plan.thresholds.push_back(*options.min_score);
      continue;
    }
    const auto it = c.thresholds.find({strategy.codebook, strategy.activation.strategy, strategy.weighting});
    if (it == c.thresholds.end()) {
      throw Error(ErrorCode::kInvalidInput, "the model has no threshold for category '" + c.name + "' with " +
                                                toString(strategy.codebook) + "/" +
                                                toString(strategy.activation.strategy) + "/" +
                                                toString(strategy.weighting) + "; pass a minimum score");
    }
    plan.thresholds.push_back(it->second);
  }
  return plan;
}

void recognizePlanned(const Model& model, const Plan& plan, const Features& features, const RecognitionOptions& options,
                      RecognitionResult& result) {
  const Strategy& strategy = options.strategy;
  result.keypoints = features.size();
  throwIfStopped(options.should_stop, "codeword activation");

  // One activation serves every category with the global codebook; separated codebooks each need their own.
  const bool global = strategy.codebook == CodebookType::kGlobal;
  std::vector<std::vector<Activation>> activations(plan.categories.size());
  {
    ScopedStage stage(&result.timings, "activate");
    for (size_t s = 0; s < plan.categories.size() && !(global && s > 0); ++s) {
      const CategoryModel& c = model.categories[static_cast<size_t>(plan.categories[s])];
      const Codebook& codebook = global ? *model.global_codebook : *c.own_codebook;
      activations[s] = codebook.activate(features.descriptors, strategy.activation);
      throwIfStopped(options.should_stop, "codeword activation");
    }
  }

  // One category's Hough space at a time: it is the bulk of the memory on a room scan.
  std::vector<Hypothesis> all;
  double vote_ms = 0, peak_ms = 0;
  const auto elapsed_ms = [](std::chrono::steady_clock::time_point since) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since).count();
  };
  for (size_t s = 0; s < plan.categories.size(); ++s) {
    const std::vector<Activation>& activated = activations[global ? 0 : s];
    auto start = std::chrono::steady_clock::now();
    const HoughSpace hough(model, plan.categories[s], features, activated, strategy);
    vote_ms += elapsed_ms(start);
    throwIfStopped(options.should_stop, "voting");
    start = std::chrono::steady_clock::now();
    auto peaks = hough.findPeaks(plan.thresholds[s]);
    std::move(peaks.begin(), peaks.end(), std::back_inserter(all));
    peak_ms += elapsed_ms(start);
    throwIfStopped(options.should_stop, "hypothesis search");
    if (options.keep_votes) {
      auto votes = castVotes(model, plan.categories[s], features, activated, strategy);
      std::move(votes.begin(), votes.end(), std::back_inserter(result.votes));
    }
  }
  result.timings.add("vote", vote_ms);
  result.timings.add("hypotheses", peak_ms);

  {
    ScopedStage stage(&result.timings, "select");
    std::stable_sort(all.begin(), all.end(),
                     [](const Hypothesis& a, const Hypothesis& b) { return a.relativeScore() > b.relativeScore(); });
    for (auto& h : all) {
      if (!options.return_keypoints) h.support_keypoints = {};
      auto& target = (h.passed_selection || !options.box_selection) ? result.hypotheses : result.rejected;
      target.push_back(std::move(h));
    }
    if (options.max_hypotheses > 0 && result.hypotheses.size() > static_cast<size_t>(options.max_hypotheses)) {
      result.hypotheses.resize(static_cast<size_t>(options.max_hypotheses));
    }
  }
  if (options.keep_votes) result.keypoint_positions = features.positions;
}

}  // namespace

RecognitionResult recognizeFeatures(const Model& model, const Features& features, const RecognitionOptions& options) {
  const Plan plan = planRecognition(model, options);
  RecognitionResult result;
  recognizePlanned(model, plan, features, options, result);
  return result;
}

RecognitionResult recognize(const Model& model, const Scene& scene, const RecognitionOptions& options) {
  if (!scene.cloud || scene.cloud->empty()) {
    throw Error(ErrorCode::kInvalidInput, "scene " + scene.source + " has no points");
  }
  const Plan plan = planRecognition(model, options);
  RecognitionResult result;
  const FrontEndResult front = extractFeatures(scene, model.front_end, model.front_end.smoothing.enabled,
                                               &result.timings, options.should_stop);
  result.input_points = front.input_points;
  result.surface_points = front.surface ? front.surface->size() : 0;
  recognizePlanned(model, plan, front.features, options, result);
  return result;
}

}  // namespace ism
