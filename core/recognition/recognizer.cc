#include "core/recognition/recognizer.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <iterator>
#include <limits>
#include <optional>

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
// Without branches: whether a vote is inside is as good as random.
bool insideCube(const Eigen::Vector3f& p, const Eigen::Vector3f& center, float half_edge) {
  const Eigen::Vector3f d = (p - center).cwiseAbs();
  return (d.x() <= half_edge) & (d.y() <= half_edge) & (d.z() <= half_edge);
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

// neighbourhood() runs in key order: the offsets before the centre's lead to lower coordinates.
constexpr size_t kCentre = 13;

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

// A ShouldStop polled by the threads of a loop over keypoints, every few keypoints: casting
// every vote of a scene can take seconds, and a caller that is gone should not wait for that.
// Once it says stop, every thread leaves its range and check() throws.
class LoopStop {
 public:
  static constexpr size_t kKeypointsPerPoll = 16;

  explicit LoopStop(const ShouldStop& should_stop) : should_stop_(should_stop) {}
  // For the i-th keypoint of a thread's range.
  bool operator()(size_t i) {
    if (stopped_.load(std::memory_order_relaxed)) return true;
    if (!should_stop_ || i % kKeypointsPerPoll != 0 || !should_stop_()) return false;
    stopped_ = true;
    return true;
  }
  void check(const char* stage) const {
    if (stopped_) throw Error(ErrorCode::kCancelled, std::string("stopped during ") + stage);
  }

 private:
  const ShouldStop& should_stop_;
  std::atomic<bool> stopped_{false};
};

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
        offsets_(features.size() + 1, 0),
        vote_offsets_(features.size() + 1, 0) {
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
    for (const auto& a : activations) vote_offsets_[static_cast<size_t>(a.keypoint) + 1] += table_.occurrences(a.codeword);
    for (size_t k = 0; k < features.size(); ++k) vote_offsets_[k + 1] += vote_offsets_[k];
    by_keypoint_.resize(activations.size());
    std::vector<uint32_t> cursor(offsets_.begin(), offsets_.end() - 1);
    for (const auto& a : activations) by_keypoint_[cursor[static_cast<size_t>(a.keypoint)]++] = a;
    // The activated codewords' votes de-interleaved (the rotation then runs four votes at a time),
    // and the longest of each.
    const size_t stored = table_.vectors.size();
    vx_.reset(new float[stored]);
    vy_.reset(new float[stored]);
    vz_.reset(new float[stored]);
    longest_.assign(static_cast<size_t>(codewords), kNotActivated);
    for (const auto& a : activations) {
      const auto codeword = static_cast<size_t>(a.codeword);
      float& longest = longest_[codeword];
      if (longest != kNotActivated) continue;
      float squared = 0;
      for (uint32_t v = table_.offsets[codeword]; v < table_.offsets[codeword + 1]; ++v) {
        const Eigen::Vector3f& vote = table_.vectors[v];
        vx_[v] = vote.x();
        vy_[v] = vote.y();
        vz_[v] = vote.z();
        squared = std::max(squared, vote.squaredNorm());
        finite_ = finite_ && std::isfinite(vote.squaredNorm());
      }
      longest = std::sqrt(squared);
    }
  }

  const CategoryModel& category() const { return category_; }
  const Features& features() const { return features_; }
  size_t keypoints() const { return features_.size(); }
  size_t votes() const { return votes_; }

  // Bounds that hold every vote: a vote lands at o + R^T v, whose coordinate i lies within
  // |column i of R| * |v| of o's (Cauchy-Schwarz), |v| at most the longest vote of the keypoint's
  // activated codewords. False when nothing votes or a bound is not finite.
  bool voteBounds(Eigen::Vector3f& lo, Eigen::Vector3f& hi) const {
    if (!finite_) return false;
    lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
    hi = -lo;
    bool any = false;
    for (size_t k = 0; k < keypoints(); ++k) {
      float reach = -1;
      for (uint32_t i = offsets_[k]; i < offsets_[k + 1]; ++i) {
        const int codeword = by_keypoint_[i].codeword;
        if (table_.occurrences(codeword) > 0) reach = std::max(reach, longest_[static_cast<size_t>(codeword)]);
      }
      if (reach < 0) continue;  // no votes
      const Eigen::Vector3f extent = features_.lrfs[k].colwise().norm().transpose() * reach;
      const Eigen::Vector3f& o = features_.positions[k];
      if (!(o - extent).allFinite() || !(o + extent).allFinite()) return false;
      lo = lo.cwiseMin(o - extent);
      hi = hi.cwiseMax(o + extent);
      any = true;
    }
    return any;
  }

  // The index of keypoint k's first vote in the order votes are cast (forEachChunk).
  size_t firstVote(size_t k) const { return vote_offsets_[k]; }

  // Calls f(weight, first, last) for each of keypoint k's activations with votes, in order: its
  // votes are those of table_ rows [first, last), each with that weight.
  template <typename F>
  void forEachActivation(size_t k, F&& f) const {
    const uint32_t begin = offsets_[k], end = offsets_[k + 1];
    const float activated = static_cast<float>(end - begin);
    for (uint32_t i = begin; i < end; ++i) {
      const Activation& a = by_keypoint_[i];
      const uint32_t first = table_.offsets[static_cast<size_t>(a.codeword)];
      const uint32_t last = table_.offsets[static_cast<size_t>(a.codeword) + 1];
      if (first == last) continue;
      float weight = 1.0f;
      if (weighting_ != VoteWeighting::kCategorization) {
        weight = 1.0f / (activated * static_cast<float>(last - first));
        if (weighting_ == VoteWeighting::kActivation) weight *= 1.0f - a.distance / 2.0f;
      }
      f(weight, first, last);
    }
  }

  // Calls f(chunk) for the votes of keypoint k, chunk by chunk.
  template <typename F>
  void forEachChunk(size_t k, VoteChunk& chunk, F&& f) const {
    const Eigen::Matrix3f& r = features_.lrfs[k];  // scene -> LRF; votes go back with its transpose
    const Eigen::Vector3f& o = features_.positions[k];
    forEachActivation(k, [&](float weight, uint32_t first, uint32_t last) {
      chunk.weight = weight;
      for (uint32_t start = first; start < last; start += kChunk) {
        chunk.size = std::min(kChunk, last - start);
        const float *vx = vx_.get() + start, *vy = vy_.get() + start, *vz = vz_.get() + start;
        // One coordinate per loop: four coefficients, which stay in registers.
        for (uint32_t j = 0; j < chunk.size; ++j) chunk.x[j] = cast(o.x(), r(0, 0), r(1, 0), r(2, 0), vx[j], vy[j], vz[j]);
        for (uint32_t j = 0; j < chunk.size; ++j) chunk.y[j] = cast(o.y(), r(0, 1), r(1, 1), r(2, 1), vx[j], vy[j], vz[j]);
        for (uint32_t j = 0; j < chunk.size; ++j) chunk.z[j] = cast(o.z(), r(0, 2), r(1, 2), r(2, 2), vx[j], vy[j], vz[j]);
        f(static_cast<const VoteChunk&>(chunk));
      }
    });
  }

  // Where vote v (a row of table_) of keypoint k lands: the same floats forEachChunk gives it.
  Eigen::Vector3f position(size_t k, uint32_t v) const {
    const Eigen::Matrix3f& r = features_.lrfs[k];
    const Eigen::Vector3f& o = features_.positions[k];
    return {cast(o.x(), r(0, 0), r(1, 0), r(2, 0), vx_[v], vy_[v], vz_[v]),
            cast(o.y(), r(0, 1), r(1, 1), r(2, 1), vx_[v], vy_[v], vz_[v]),
            cast(o.z(), r(0, 2), r(1, 2), r(2, 2), vx_[v], vy_[v], vz_[v])};
  }

 private:
  // One coordinate of a vote: o + column of R . v, in this order of operations everywhere.
  static float cast(float o, float r0, float r1, float r2, float vx, float vy, float vz) {
    return o + (r0 * vx + r1 * vy + r2 * vz);
  }

  const CategoryModel& category_;
  const VoteTable& table_;
  const Features& features_;
  VoteWeighting weighting_;
  std::vector<uint32_t> offsets_;  // activations of keypoint k: by_keypoint_[offsets_[k] .. offsets_[k+1])
  std::vector<size_t> vote_offsets_;  // votes of keypoint k: [vote_offsets_[k], vote_offsets_[k+1])
  std::vector<Activation> by_keypoint_;
  size_t votes_ = 0;
  // The vectors of table_ by coordinate, filled for the activated codewords only.
  std::unique_ptr<float[]> vx_, vy_, vz_;
  static constexpr float kNotActivated = -1;
  std::vector<float> longest_;  // per codeword: its longest vote, or kNotActivated
  bool finite_ = true;          // every activated codeword's votes
};

// What a Hough bin keeps of its votes: enough for the peak test and the peak's centre.
struct BinSum {
  double weight = 0;
  double x = 0, y = 0, z = 0;  // weighted position sum
};

struct Range {
  uint32_t begin = 0, end = 0;
};

// The bins of a box that holds every vote, in blocks of 4 x 4 x 4 bins allocated when a vote
// first lands in one and found through a table over the box's blocks: no hashing and no probing,
// a vote costs one lookup in a table that stays in the cache. A Kinect frame's box is mostly empty
// (its keypoints lie metres apart, their votes near the surfaces): the memory follows the occupied
// blocks, not the box. (One array over the whole box, 17 MB per category on tum_desk, was as fast
// once warm, but the first touch of its pages took as long again as the votes.) Bins are addressed
// relative to the box's first bin; blocks and the bins in a block run in key order, the last
// coordinate fastest.
class BinGrid {
 public:
  static constexpr int kShift = 2;  // 2^kShift bins along each axis of a block
  static constexpr int32_t kMask = (1 << kShift) - 1, kBlockBins = 1 << (3 * kShift);

  BinGrid(const Eigen::Vector3i& first, const Eigen::Vector3i& bins)
      : first_(first), blocks_((bins.array() + kMask) / (kMask + 1)),
        table_(static_cast<size_t>(blocks_.prod()), nullptr) {}

  const Eigen::Vector3i& first() const { return first_; }  // coordinates of bin (0, 0, 0)
  size_t tableSize() const { return table_.size(); }
  const std::vector<int32_t>& allocated() const { return allocated_; }  // blocks in allocation order

  int32_t blockOf(int32_t x, int32_t y, int32_t z) const {
    return ((x >> kShift) * blocks_.y() + (y >> kShift)) * blocks_.z() + (z >> kShift);
  }
  static int32_t placeOf(int32_t x, int32_t y, int32_t z) {
    return (x & kMask) << (2 * kShift) | (y & kMask) << kShift | (z & kMask);
  }
  Eigen::Vector3i binOf(int32_t block, int32_t place) const {
    const Eigen::Vector3i b(block / (blocks_.y() * blocks_.z()), block / blocks_.z() % blocks_.y(), block % blocks_.z());
    return b * (kMask + 1) + Eigen::Vector3i(place >> (2 * kShift), place >> kShift & kMask, place & kMask);
  }

  BinSum* block(int32_t b) {  // allocated on first use
    BinSum*& bins = table_[static_cast<size_t>(b)];
    if (bins == nullptr) bins = allocate(b);
    return bins;
  }
  const BinSum* block(int32_t b) const { return table_[static_cast<size_t>(b)]; }
  const BinSum* find(const Eigen::Vector3i& bin) const {
    const BinSum* bins = block(blockOf(bin.x(), bin.y(), bin.z()));
    return bins == nullptr ? nullptr : bins + placeOf(bin.x(), bin.y(), bin.z());
  }

 private:
  static constexpr int32_t kSlabBlocks = 32;  // blocks per allocation: 64 KB

  BinSum* allocate(int32_t b) {
    if (allocated_.size() % kSlabBlocks == 0) slabs_.emplace_back(new BinSum[kSlabBlocks * kBlockBins]);
    BinSum* bins = slabs_.back().get() + allocated_.size() % kSlabBlocks * kBlockBins;
    allocated_.push_back(b);
    return bins;
  }

  Eigen::Vector3i first_, blocks_;
  std::vector<BinSum*> table_;
  std::vector<int32_t> allocated_;
  std::vector<std::unique_ptr<BinSum[]>> slabs_;
};

struct GridBox {
  Eigen::Vector3i first, bins;  // the first bin's coordinates, bins along each axis
};

// A grid's bins stay within the range of a BinKey, where a float vote position times
// 1 / bin_size is off by well under a bin (floats near 2^20 lie 1/8 apart).
constexpr int64_t kGridBinRange = kBinOffset;

// The box that holds every vote of the caster, one bin wider on each side for the rounding of the
// vote positions and one more for the neighbours of the peak test. None when it has more than
// `max_bins` (or kMaxGridBins) bins, more blocks than votes (the table would cost more than the
// votes), or does not fit the key range.
std::optional<GridBox> gridBox(const VoteCaster& caster, float inverse_bin_size, size_t max_bins) {
  Eigen::Vector3f lo, hi;
  if (max_bins == 0 || !caster.voteBounds(lo, hi)) return std::nullopt;
  GridBox box;
  for (int a = 0; a < 3; ++a) {
    const double low = std::floor(static_cast<double>(lo[a]) * inverse_bin_size) - 2;
    const double high = std::floor(static_cast<double>(hi[a]) * inverse_bin_size) + 2;
    if (!(low >= -kGridBinRange && high < kGridBinRange)) return std::nullopt;
    box.first[a] = static_cast<int32_t>(low);
    box.bins[a] = static_cast<int32_t>(high - low) + 1;
  }
  const double count = static_cast<double>(box.bins.x()) * box.bins.y() * box.bins.z();
  const double votes = static_cast<double>(caster.votes());
  const double limit = static_cast<double>(std::min(max_bins, HoughSpace::kMaxGridBins));  // int32 indices
  if (count > limit || count > BinGrid::kBlockBins * votes) return std::nullopt;
  return box;
}

// The blocks and places of a chunk's bins in a grid that holds them.
struct ChunkCells {
  alignas(16) int32_t block[kChunk], place[kChunk];
  ChunkCells(const VoteChunk& chunk, float inverse_bin_size, const BinGrid& grid) {
    const Eigen::Vector3i& first = grid.first();
    for (uint32_t j = 0; j < chunk.size; ++j) {
      const int32_t x = floorToInt(chunk.x[j] * inverse_bin_size) - first.x();
      const int32_t y = floorToInt(chunk.y[j] * inverse_bin_size) - first.y();
      const int32_t z = floorToInt(chunk.z[j] * inverse_bin_size) - first.z();
      block[j] = grid.blockOf(x, y, z);
      place[j] = BinGrid::placeOf(x, y, z);
    }
  }
};

void add(BinSum& sum, double w, float x, float y, float z) {
  sum.weight += w;
  sum.x += w * x;
  sum.y += w * y;
  sum.z += w * z;
}

void add(BinSum& sum, const BinSum& part) {
  sum.weight += part.weight;
  sum.x += part.x;
  sum.y += part.y;
  sum.z += part.z;
}

}  // namespace

struct HoughSpace::Impl {
  VoteCaster caster;
  float inverse_bin_size;
  std::optional<BinGrid> grid;  // the bins when set, else `hashed`
  BinMap<BinSum> hashed;
  // With the grid: vote i's bin, block * kBlockBins + place, in the order votes are cast; or empty.
  std::vector<uint32_t> vote_bins;
};

HoughSpace::HoughSpace(const Model& model, int category_index, const Features& features,
                       const std::vector<Activation>& activations, const Strategy& strategy, size_t max_grid_bins,
                       size_t max_kept_vote_bins, const ShouldStop& should_stop)
    : impl_(new Impl{VoteCaster(model, category_index, features, activations, strategy), 0, std::nullopt, {}}) {
  Impl& impl = *impl_;
  LoopStop stop(should_stop);
  const VoteCaster& caster = impl.caster;
  const float inverse_bin_size = impl.inverse_bin_size = 1.0f / caster.category().bin_size;
  if (const std::optional<GridBox> box = gridBox(caster, inverse_bin_size, max_grid_bins)) {
    const bool keep_bins = caster.votes() <= std::min(max_kept_vote_bins, kMaxKeptVoteBins);
    if (keep_bins) impl.vote_bins.resize(caster.votes());
    auto parts = perThreadRanges<std::optional<BinGrid>>(caster.keypoints(), kKeypointsPerThread,
                                                         [&](std::optional<BinGrid>& grid, size_t begin, size_t end) {
      grid.emplace(box->first, box->bins);
      VoteChunk chunk;
      for (size_t k = begin; k < end && !stop(k - begin); ++k) {
        uint32_t* kept = keep_bins ? impl.vote_bins.data() + caster.firstVote(k) : nullptr;
        caster.forEachChunk(k, chunk, [&](const VoteChunk& votes) {
          const ChunkCells in(votes, inverse_bin_size, *grid);
          for (uint32_t j = 0; j < votes.size; ++j) {
            add(grid->block(in.block[j])[in.place[j]], votes.weight, votes.x[j], votes.y[j], votes.z[j]);
          }
          if (kept == nullptr) return;
          for (uint32_t j = 0; j < votes.size; ++j) {
            *kept++ = static_cast<uint32_t>(in.block[j]) * BinGrid::kBlockBins + static_cast<uint32_t>(in.place[j]);
          }
        });
      }
    });
    stop.check("voting");
    impl.grid = std::move(parts[0]);
    for (size_t t = 1; t < parts.size(); ++t) {
      for (const int32_t b : parts[t]->allocated()) {
        BinSum* sum = impl.grid->block(b);
        const BinSum* part = parts[t]->block(b);
        for (int32_t i = 0; i < BinGrid::kBlockBins; ++i) add(sum[i], part[i]);
      }
      parts[t].reset();
    }
    return;
  }
  auto parts = perThreadRanges<BinMap<BinSum>>(caster.keypoints(), kKeypointsPerThread,
                                               [&](BinMap<BinSum>& bins, size_t begin, size_t end) {
    VoteChunk chunk;
    for (size_t k = begin; k < end && !stop(k - begin); ++k) {
      caster.forEachChunk(k, chunk, [&](const VoteChunk& votes) {
        const ChunkBins in(votes, inverse_bin_size);
        for (uint32_t j = 0; j < votes.size; ++j) add(bins[in.key(j)], votes.weight, votes.x[j], votes.y[j], votes.z[j]);
      });
    }
  });
  stop.check("voting");
  impl.hashed = std::move(parts[0]);
  for (size_t t = 1; t < parts.size(); ++t) {
    for (const auto& slot : parts[t].slots()) {
      if (slot.key != kEmptyKey) add(impl.hashed[slot.key], slot.value);
    }
    parts[t] = {};
  }
}

HoughSpace::~HoughSpace() = default;

size_t HoughSpace::votes() const { return impl_->caster.votes(); }

size_t HoughSpace::bins() const {
  if (!impl_->grid) return impl_->hashed.size();
  size_t occupied = 0;
  for (const int32_t b : impl_->grid->allocated()) {
    const BinSum* bins = impl_->grid->block(b);
    for (int32_t i = 0; i < BinGrid::kBlockBins; ++i) {
      occupied += bins[i].weight != 0 || bins[i].x != 0 || bins[i].y != 0 || bins[i].z != 0;
    }
  }
  return occupied;
}

bool HoughSpace::gridded() const { return impl_->grid.has_value(); }

bool HoughSpace::keptVoteBins() const { return !impl_->vote_bins.empty(); }

namespace {

// A local maximum worth scoring.
struct Candidate {
  BinKey key;
  Eigen::Vector3f center;
};

// The peak test of a bin: `neighbour(i)` is its neighbour at neighbourhood()[i] (null when it has
// no votes), `lower(i)` whether that neighbour's coordinates are the lower. A candidate is a local
// maximum (ties: the lower coordinates win) whose 27 bins together exceed the threshold: a cube
// centred inside the bin lies within them.
template <typename Neighbour, typename Lower>
bool isCandidate(const BinSum& sum, float threshold, Neighbour&& neighbour, Lower&& lower) {
  if (!(sum.weight > 0)) return false;
  double bound = 0;
  for (size_t i = 0; i < neighbourhood().size(); ++i) {
    const BinSum* n = neighbour(i);
    if (n == nullptr) continue;
    if (n->weight > sum.weight || (n->weight == sum.weight && lower(i))) return false;
    bound += n->weight;
  }
  return bound > threshold;
}

Candidate candidateAt(BinKey key, const BinSum& sum) {
  return {key, (Eigen::Vector3d(sum.x, sum.y, sum.z) / sum.weight).cast<float>()};
}

// What the votes next to the candidates give them, per thread.
struct Support {
  std::vector<double> score;
  std::vector<std::vector<int>> keypoints;  // ascending, each once
};

}  // namespace

std::vector<Hypothesis> HoughSpace::findPeaks(float threshold, const ShouldStop& should_stop) const {
  const Impl& impl = *impl_;
  LoopStop stop(should_stop);
  const VoteCaster& caster = impl.caster;
  const CategoryModel& category = caster.category();
  const float bin_size = category.bin_size, half_edge = bin_size / 2;

  // Local maxima whose 27 bins together could exceed the threshold: the only bins worth scoring.
  std::vector<std::vector<Candidate>> found;
  if (impl.grid) {
    const BinGrid& grid = *impl.grid;
    // Every bin with votes lies at least one bin inside the box, so its neighbours are in it too.
    const std::vector<int32_t>& blocks = grid.allocated();
    found = perThreadRanges<std::vector<Candidate>>(blocks.size(), 1024, [&](std::vector<Candidate>& out, size_t begin,
                                                                            size_t end) {
      for (size_t i = begin; i < end; ++i) {
        const BinSum* bins = grid.block(blocks[i]);
        for (int32_t place = 0; place < BinGrid::kBlockBins; ++place) {
          if (!(bins[place].weight > 0)) continue;
          const Eigen::Vector3i bin = grid.binOf(blocks[i], place);
          const auto neighbour = [&](size_t n) { return grid.find(bin + neighbourhood()[n]); };
          const auto lower = [](size_t n) { return n < kCentre; };
          if (isCandidate(bins[place], threshold, neighbour, lower)) {
            out.push_back(candidateAt(keyOf(grid.first() + bin), bins[place]));
          }
        }
      }
    });
  } else {
    const BinMap<BinSum>& bins = impl.hashed;
    const auto& slots = bins.slots();
    found = perThreadRanges<std::vector<Candidate>>(slots.size(), 4096, [&](std::vector<Candidate>& out, size_t begin,
                                                                          size_t end) {
      for (size_t s = begin; s < end; ++s) {
        const auto& slot = slots[s];
        if (slot.key == kEmptyKey) continue;
        const Eigen::Vector3i bin = binOfKey(slot.key);
        const auto neighbour = [&](size_t i) { return bins.find(keyOf(bin + neighbourhood()[i])); };
        const auto lower = [&](size_t i) { return keyOf(bin + neighbourhood()[i]) < slot.key; };
        if (isCandidate(slot.value, threshold, neighbour, lower)) out.push_back(candidateAt(slot.key, slot.value));
      }
    });
  }
  std::vector<Candidate> candidates;
  for (auto& part : found) std::move(part.begin(), part.end(), std::back_inserter(candidates));
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) { return a.key < b.key; });
  if (candidates.empty()) return {};

  // Each bin a vote inside a candidate's cube can have -> the candidates whose cubes it meets, as
  // a range of `near`. A cube of edge bin_size meets two bins along each axis (three when the
  // rounding of a vote's bin straddles a face): 8 of the 27 neighbours of the candidate's bin,
  // which hold the cube since its centre lies in that bin.
  const float inverse_bin_size = impl.inverse_bin_size;
  std::vector<std::pair<BinKey, uint32_t>> near;
  near.reserve(candidates.size() * 8);
  for (size_t c = 0; c < candidates.size(); ++c) {
    const Eigen::Vector3i bin = binOfKey(candidates[c].key);
    Eigen::Vector3i lo, hi;
    for (int a = 0; a < 3; ++a) {
      // A vote's bin is floor(p * inverse_bin_size) in floats, and insideCube compares a float
      // difference: both off by a few units in the last place, well within the slack.
      const double center = candidates[c].center[a], slack = (std::abs(center * inverse_bin_size) + 2) * 0x1p-20;
      lo[a] = std::max(bin[a] - 1, static_cast<int>(std::floor((center - half_edge) * inverse_bin_size - slack)));
      hi[a] = std::min(bin[a] + 1, static_cast<int>(std::floor((center + half_edge) * inverse_bin_size + slack)));
    }
    for (int x = lo.x(); x <= hi.x(); ++x) {
      for (int y = lo.y(); y <= hi.y(); ++y) {
        for (int z = lo.z(); z <= hi.z(); ++z) near.emplace_back(keyOf({x, y, z}), static_cast<uint32_t>(c));
      }
    }
  }
  std::sort(near.begin(), near.end());
  std::vector<Range> ranges;  // one per bin meeting a cube
  for (uint32_t i = 0; i < near.size(); ++i) {
    if (i == 0 || near[i].first != near[i - 1].first) ranges.push_back({i, i});
    ranges.back().end = i + 1;
  }

  // Cast the votes again and look only at those in the bins of a candidate's cube. (Skipping
  // codewords whose votes are all too short to reach a candidate saved nothing measurable in room
  // scans: votes reach across the objects, candidates are all over the room.)
  const auto support = [&](Support& s, const Eigen::Vector3f& p, float weight, const Range& range, int k) {
    for (uint32_t i = range.begin; i < range.end; ++i) {
      const uint32_t c = near[i].second;
      const bool inside = insideCube(p, candidates[c].center, half_edge);
      s.score[c] += inside ? weight : 0.0f;  // adding zero to the sum changes nothing
      auto& keypoints = s.keypoints[c];
      if (inside & (keypoints.empty() || keypoints.back() != k)) keypoints.push_back(k);
    }
  };
  // Every vote once, keypoint ranges split between threads: onKeypoint(s, chunk, k) adds the
  // votes of keypoint k that land in a cube's bins (`chunk`: the thread's buffer to cast them
  // into); the storage paths differ only in finding a vote's bin.
  const auto recast = [&](const auto& onKeypoint) {
    return perThreadRanges<Support>(caster.keypoints(), kKeypointsPerThread, [&](Support& s, size_t begin, size_t end) {
      s.score.assign(candidates.size(), 0.0);
      s.keypoints.resize(candidates.size());
      VoteChunk chunk;
      for (size_t k = begin; k < end && !stop(k - begin); ++k) onKeypoint(s, chunk, k);
    });
  };
  // recast, casting each keypoint's votes again: onChunk(s, votes, k) per chunk of them.
  const auto castAgain = [&](const auto& onChunk) {
    return recast([&](Support& s, VoteChunk& chunk, size_t k) {
      caster.forEachChunk(k, chunk, [&](const VoteChunk& votes) { onChunk(s, votes, k); });
    });
  };
  // Most votes miss every cube: the (index, 1 + range) of the n votes rangeOf(j) finds near a
  // candidate are gathered without branching. Returns how many.
  const auto gatherNear = [](uint32_t n, const auto& rangeOf, uint32_t* hit, uint32_t* range) {
    uint32_t hits = 0;
    for (uint32_t j = 0; j < n; ++j) {
      const uint32_t r = rangeOf(j);
      hit[hits] = j;
      range[hits] = r;
      hits += r != 0;
    }
    return hits;
  };
  std::vector<Support> parts;
  if (impl.grid) {
    // The ranges of the bins of a block meeting a cube, 1 + index into `ranges` (0: none), in
    // blocks of near_ranges; the other blocks share the first, all zeros.
    const BinGrid& grid = *impl.grid;
    std::vector<uint32_t> near_block(grid.tableSize(), 0);
    std::vector<uint32_t> near_ranges(BinGrid::kBlockBins, 0);
    for (uint32_t r = 0; r < ranges.size(); ++r) {
      const Eigen::Vector3i bin = binOfKey(near[ranges[r].begin].first) - grid.first();
      uint32_t& slot = near_block[static_cast<size_t>(grid.blockOf(bin.x(), bin.y(), bin.z()))];
      if (slot == 0) {
        slot = static_cast<uint32_t>(near_ranges.size() / BinGrid::kBlockBins);
        near_ranges.resize(near_ranges.size() + BinGrid::kBlockBins, 0);
      }
      const auto place = static_cast<uint32_t>(BinGrid::placeOf(bin.x(), bin.y(), bin.z()));
      near_ranges[slot * BinGrid::kBlockBins + place] = r + 1;
    }
    const auto nearRange = [&](uint32_t block, uint32_t place) {
      return near_ranges[near_block[block] * BinGrid::kBlockBins + place];
    };
    if (!impl.vote_bins.empty()) {
      parts = recast([&](Support& s, VoteChunk&, size_t k) {
        const uint32_t* bin = impl.vote_bins.data() + caster.firstVote(k);
        caster.forEachActivation(k, [&](float weight, uint32_t first, uint32_t last) {
          for (uint32_t start = first; start < last; start += kChunk) {
            const uint32_t n = std::min(kChunk, last - start);
            uint32_t hit[kChunk], range[kChunk];
            const uint32_t hits = gatherNear(
                n, [&](uint32_t j) { return nearRange(bin[j] / BinGrid::kBlockBins, bin[j] % BinGrid::kBlockBins); },
                hit, range);
            for (uint32_t h = 0; h < hits; ++h) {
              support(s, caster.position(k, start + hit[h]), weight, ranges[range[h] - 1], static_cast<int>(k));
            }
            bin += n;
          }
        });
      });
    } else {
      parts = castAgain([&](Support& s, const VoteChunk& votes, size_t k) {
        const ChunkCells in(votes, inverse_bin_size, grid);
        uint32_t hit[kChunk], range[kChunk];
        const uint32_t hits = gatherNear(
            votes.size,
            [&](uint32_t j) { return nearRange(static_cast<uint32_t>(in.block[j]), static_cast<uint32_t>(in.place[j])); },
            hit, range);
        for (uint32_t h = 0; h < hits; ++h) {
          support(s, votes.position(hit[h]), votes.weight, ranges[range[h] - 1], static_cast<int>(k));
        }
      });
    }
  } else {
    BinMap<uint32_t> range_of;  // 1 + the range of a bin
    // Most votes land far from every candidate. A 32 KB bitmap of the bins near candidates (one
    // bit per Fibonacci hash of the key) stays in L1 and turns those votes away before the
    // full-mix hash probe into range_of, which misses the cache on large scenes.
    constexpr int kFilterBits = 18;
    std::vector<uint64_t> near_filter(size_t{1} << (kFilterBits - 6), 0);
    const auto filterBit = [](BinKey key) { return (key * 0x9E3779B97F4A7C15ull) >> (64 - kFilterBits); };
    for (uint32_t r = 0; r < ranges.size(); ++r) {
      const BinKey key = near[ranges[r].begin].first;
      range_of[key] = r + 1;
      const uint64_t bit = filterBit(key);
      near_filter[bit >> 6] |= uint64_t{1} << (bit & 63);
    }
    parts = castAgain([&](Support& s, const VoteChunk& votes, size_t k) {
      const ChunkBins in(votes, inverse_bin_size);
      for (uint32_t j = 0; j < votes.size; ++j) {
        const BinKey key = in.key(j);
        const uint64_t bit = filterBit(key);
        if (!(near_filter[bit >> 6] >> (bit & 63) & 1)) continue;
        const uint32_t* r = range_of.find(key);
        if (r != nullptr) support(s, votes.position(j), votes.weight, ranges[*r - 1], static_cast<int>(k));
      }
    });
  }

  stop.check("hypothesis search");

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
    const HoughSpace hough(model, plan.categories[s], features, activated, strategy, HoughSpace::kMaxGridBins,
                           HoughSpace::kMaxKeptVoteBins, options.should_stop);
    vote_ms += elapsed_ms(start);
    throwIfStopped(options.should_stop, "voting");
    start = std::chrono::steady_clock::now();
    auto peaks = hough.findPeaks(plan.thresholds[s], options.should_stop);
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
  result.surface_points = front.surface_points;
  recognizePlanned(model, plan, front.features, options, result);
  return result;
}

}  // namespace ism
