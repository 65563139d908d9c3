#include "core/recognition/hough_space.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <limits>
#include <optional>
#include <utility>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/common/error.h"
#include "core/common/hash.h"
#include "core/recognition/box_selection.h"
#include "core/recognition/voting.h"

namespace ism {
namespace {

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
// blocks, not the box. (One array over the whole box, 17 MB per category on tum_desk, would be as
// fast once warm, but the first touch of its pages costs as much again as the votes.) Bins are
// addressed relative to the box's first bin; blocks and the bins in a block run in key order, the
// last coordinate fastest.
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

// The candidate centred at the weighted mean of the votes in its bin and the bins `neighbour` finds
// (null where they hold none), kept inside its bin [lo, lo + bin_size]: a cube of edge bin_size
// centred there lies within the 27 bins whose votes findPeaks places again.
template <typename Neighbour>
Candidate candidateAround(BinKey key, const BinSum& sum, PeakCentre centre, float bin_size, Neighbour&& neighbour) {
  Candidate c = candidateAt(key, sum);
  if (centre == PeakCentre::kBin) return c;
  BinSum total{};
  for (size_t i = 0; i < neighbourhood().size(); ++i) {
    if (const BinSum* n = neighbour(i)) add(total, *n);
  }
  const Eigen::Vector3f lo = binOfKey(key).cast<float>() * bin_size;
  c.center = candidateAt(key, total).center.cwiseMax(lo).cwiseMin(lo + Eigen::Vector3f::Constant(bin_size));
  return c;
}

// The threads' candidates in one list, in key order.
std::vector<Candidate> inKeyOrder(std::vector<std::vector<Candidate>> found) {
  std::vector<Candidate> candidates;
  for (auto& part : found) std::move(part.begin(), part.end(), std::back_inserter(candidates));
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) { return a.key < b.key; });
  return candidates;
}

// Local maxima whose 27 bins together could exceed the threshold: the only bins worth scoring.
std::vector<Candidate> findCandidates(const BinGrid& grid, float threshold, PeakCentre centre, float bin_size) {
  // Every bin with votes lies at least one bin inside the box, so its neighbours are in it too.
  const std::vector<int32_t>& blocks = grid.allocated();
  return inKeyOrder(perThreadRanges<std::vector<Candidate>>(
      blocks.size(), 1024, [&](std::vector<Candidate>& out, size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
          const BinSum* bins = grid.block(blocks[i]);
          for (int32_t place = 0; place < BinGrid::kBlockBins; ++place) {
            if (!(bins[place].weight > 0)) continue;
            const Eigen::Vector3i bin = grid.binOf(blocks[i], place);
            const auto neighbour = [&](size_t n) { return grid.find(bin + neighbourhood()[n]); };
            const auto lower = [](size_t n) { return n < kCentre; };
            if (isCandidate(bins[place], threshold, neighbour, lower)) {
              out.push_back(candidateAround(keyOf(grid.first() + bin), bins[place], centre, bin_size, neighbour));
            }
          }
        }
      }));
}

std::vector<Candidate> findCandidates(const BinMap<BinSum>& bins, float threshold, PeakCentre centre, float bin_size) {
  const auto& slots = bins.slots();
  return inKeyOrder(perThreadRanges<std::vector<Candidate>>(
      slots.size(), 4096, [&](std::vector<Candidate>& out, size_t begin, size_t end) {
        for (size_t s = begin; s < end; ++s) {
          const auto& slot = slots[s];
          if (slot.key == kEmptyKey) continue;
          const Eigen::Vector3i bin = binOfKey(slot.key);
          const auto neighbour = [&](size_t i) { return bins.find(keyOf(bin + neighbourhood()[i])); };
          const auto lower = [&](size_t i) { return keyOf(bin + neighbourhood()[i]) < slot.key; };
          if (isCandidate(slot.value, threshold, neighbour, lower)) {
            out.push_back(candidateAround(slot.key, slot.value, centre, bin_size, neighbour));
          }
        }
      }));
}

// The candidates' cubes and the bins they meet: each bin a vote inside a cube can have, with the
// candidates whose cubes meet it as a range of `near`. A cube of edge bin_size meets two bins
// along each axis (three when the rounding of a vote's bin straddles a face): 8 of the 27
// neighbours of the candidate's bin, which hold the cube since its centre lies in that bin.
// What the votes next to the candidates give them, per thread.
struct Support {
  std::vector<double> score;
  std::vector<std::vector<int>> keypoints;  // ascending, each once
};

struct CandidateCubes {
  const std::vector<Candidate>& candidates;
  float half_edge;
  std::vector<std::pair<BinKey, uint32_t>> near;  // (bin, candidate), in key order
  std::vector<Range> ranges;  // one per bin meeting a cube: its run of `near`

  // Adds the vote at `p` of keypoint k to the candidates of range r whose cube holds it.
  void addVote(Support& s, const Eigen::Vector3f& p, float weight, uint32_t r, int k) const {
    const Range& range = ranges[r];
    for (uint32_t i = range.begin; i < range.end; ++i) {
      const uint32_t c = near[i].second;
      const bool inside = insideCube(p, candidates[c].center, half_edge);
      s.score[c] += inside ? weight : 0.0f;  // adding zero to the sum changes nothing
      auto& keypoints = s.keypoints[c];
      if (inside & (keypoints.empty() || keypoints.back() != k)) keypoints.push_back(k);
    }
  }
};

CandidateCubes candidateCubes(const std::vector<Candidate>& candidates, float bin_size, float inverse_bin_size) {
  CandidateCubes cubes{candidates, bin_size / 2, {}, {}};
  const float half_edge = cubes.half_edge;
  auto& near = cubes.near;
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
  for (uint32_t i = 0; i < near.size(); ++i) {
    if (i == 0 || near[i].first != near[i - 1].first) cubes.ranges.push_back({i, i});
    cubes.ranges.back().end = i + 1;
  }
  return cubes;
}

// Every vote once, keypoint ranges split between threads: onKeypoint(s, chunk, k) adds the
// votes of keypoint k that land in a cube's bins (`chunk`: the thread's buffer to cast them
// into); the storage paths differ only in finding a vote's bin.
template <typename OnKeypoint>
std::vector<Support> supportPerKeypoint(const VoteCaster& caster, size_t candidates, LoopStop& stop,
                                        const OnKeypoint& onKeypoint) {
  return perThreadRanges<Support>(caster.keypoints(), kKeypointsPerThread, [&](Support& s, size_t begin, size_t end) {
    s.score.assign(candidates, 0.0);
    s.keypoints.resize(candidates);
    VoteChunk chunk;
    for (size_t k = begin; k < end && !stop(k - begin); ++k) onKeypoint(s, chunk, k);
  });
}

// supportPerKeypoint, casting each keypoint's votes again: onChunk(s, votes, k) per chunk of them.
template <typename OnChunk>
std::vector<Support> supportPerChunk(const VoteCaster& caster, size_t candidates, LoopStop& stop,
                                     const OnChunk& onChunk) {
  return supportPerKeypoint(caster, candidates, stop, [&](Support& s, VoteChunk& chunk, size_t k) {
    caster.forEachChunk(k, chunk, [&](const VoteChunk& votes) { onChunk(s, votes, k); });
  });
}

// Most votes miss every cube: the (index, 1 + range) of the n votes rangeOf(j) finds near a
// candidate are gathered without branching. Returns how many.
template <typename RangeOf>
uint32_t gatherNear(uint32_t n, const RangeOf& rangeOf, uint32_t* hit, uint32_t* range) {
  uint32_t hits = 0;
  for (uint32_t j = 0; j < n; ++j) {
    const uint32_t r = rangeOf(j);
    hit[hits] = j;
    range[hits] = r;
    hits += r != 0;
  }
  return hits;
}

// The ranges of the bins of a grid block meeting a cube, 1 + index into CandidateCubes::ranges
// (0: none), in blocks of `ranges`; the blocks that meet no cube share the first, all zeros.
class GridRanges {
 public:
  GridRanges(const BinGrid& grid, const CandidateCubes& cubes)
      : block_(grid.tableSize(), 0), ranges_(BinGrid::kBlockBins, 0) {
    for (uint32_t r = 0; r < cubes.ranges.size(); ++r) {
      const Eigen::Vector3i bin = binOfKey(cubes.near[cubes.ranges[r].begin].first) - grid.first();
      uint32_t& slot = block_[static_cast<size_t>(grid.blockOf(bin.x(), bin.y(), bin.z()))];
      if (slot == 0) {
        slot = static_cast<uint32_t>(ranges_.size() / BinGrid::kBlockBins);
        ranges_.resize(ranges_.size() + BinGrid::kBlockBins, 0);
      }
      const auto place = static_cast<uint32_t>(BinGrid::placeOf(bin.x(), bin.y(), bin.z()));
      ranges_[slot * BinGrid::kBlockBins + place] = r + 1;
    }
  }

  uint32_t operator()(uint32_t block, uint32_t place) const {
    return ranges_[block_[block] * BinGrid::kBlockBins + place];
  }

 private:
  std::vector<uint32_t> block_;
  std::vector<uint32_t> ranges_;
};

// With each vote's bin kept: only the votes in a cube's bins are placed again.
std::vector<Support> supportFromKeptBins(const VoteCaster& caster, const GridRanges& nearRange,
                                         const std::vector<uint32_t>& vote_bins, const CandidateCubes& cubes,
                                         LoopStop& stop) {
  return supportPerKeypoint(caster, cubes.candidates.size(), stop, [&](Support& s, VoteChunk&, size_t k) {
    const uint32_t* bin = vote_bins.data() + caster.firstVote(k);
    caster.forEachActivation(k, [&](float weight, uint32_t first, uint32_t last) {
      for (uint32_t start = first; start < last; start += kChunk) {
        const uint32_t n = std::min(kChunk, last - start);
        uint32_t hit[kChunk], range[kChunk];
        const uint32_t hits = gatherNear(
            n, [&](uint32_t j) { return nearRange(bin[j] / BinGrid::kBlockBins, bin[j] % BinGrid::kBlockBins); },
            hit, range);
        for (uint32_t h = 0; h < hits; ++h) {
          cubes.addVote(s, caster.position(k, start + hit[h]), weight, range[h] - 1, static_cast<int>(k));
        }
        bin += n;
      }
    });
  });
}

// Gridded bins without each vote's: every vote cast again and looked up in the grid.
std::vector<Support> supportFromGrid(const VoteCaster& caster, const BinGrid& grid, float inverse_bin_size,
                                     const GridRanges& nearRange, const CandidateCubes& cubes, LoopStop& stop) {
  return supportPerChunk(caster, cubes.candidates.size(), stop, [&](Support& s, const VoteChunk& votes, size_t k) {
    const ChunkCells in(votes, inverse_bin_size, grid);
    uint32_t hit[kChunk], range[kChunk];
    const uint32_t hits = gatherNear(
        votes.size,
        [&](uint32_t j) { return nearRange(static_cast<uint32_t>(in.block[j]), static_cast<uint32_t>(in.place[j])); },
        hit, range);
    for (uint32_t h = 0; h < hits; ++h) {
      cubes.addVote(s, votes.position(hit[h]), votes.weight, range[h] - 1, static_cast<int>(k));
    }
  });
}

// Hashed bins: every vote cast again, its bin's key looked up.
std::vector<Support> supportFromKeys(const VoteCaster& caster, float inverse_bin_size, const CandidateCubes& cubes,
                                     LoopStop& stop) {
  BinMap<uint32_t> range_of;  // 1 + the range of a bin
  // Most votes land far from every candidate. A 32 KB bitmap of the bins near candidates (one
  // bit per Fibonacci hash of the key) stays in L1 and turns those votes away before the
  // full-mix hash probe into range_of, which misses the cache on large scenes.
  constexpr int kFilterBits = 18;
  std::vector<uint64_t> near_filter(size_t{1} << (kFilterBits - 6), 0);
  const auto filterBit = [](BinKey key) { return (key * 0x9E3779B97F4A7C15ull) >> (64 - kFilterBits); };
  for (uint32_t r = 0; r < cubes.ranges.size(); ++r) {
    const BinKey key = cubes.near[cubes.ranges[r].begin].first;
    range_of[key] = r + 1;
    const uint64_t bit = filterBit(key);
    near_filter[bit >> 6] |= uint64_t{1} << (bit & 63);
  }
  return supportPerChunk(caster, cubes.candidates.size(), stop, [&](Support& s, const VoteChunk& votes, size_t k) {
    const ChunkBins in(votes, inverse_bin_size);
    for (uint32_t j = 0; j < votes.size; ++j) {
      const BinKey key = in.key(j);
      const uint64_t bit = filterBit(key);
      if (!(near_filter[bit >> 6] >> (bit & 63) & 1)) continue;
      const uint32_t* r = range_of.find(key);
      if (r != nullptr) cubes.addVote(s, votes.position(j), votes.weight, *r - 1, static_cast<int>(k));
    }
  });
}

// The candidates whose summed support exceeds the threshold, as hypotheses with their
// supporting keypoints and box, in candidate order.
std::vector<Hypothesis> hypothesesAbove(float threshold, const CategoryModel& category, const Features& features,
                                        const std::vector<Candidate>& candidates, const std::vector<Support>& parts) {
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
    std::vector<int> support;
    for (const auto& part : parts) {  // ranges in keypoint order: concatenated, still each once
      support.insert(support.end(), part.keypoints[c].begin(), part.keypoints[c].end());
    }
    setSupport(h, std::move(support), features);
    h.box = fitOrientedBox(h.support_keypoints);
    h.passed_selection = passesBoxSelection(h.box, category.box);
    peaks.push_back(std::move(h));
  }
  return peaks;
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

const VoteCaster& HoughSpace::caster() const { return impl_->caster; }

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

const char* toString(PeakCentre centre) { return centre == PeakCentre::kBin ? "bin" : "neighbourhood"; }

std::vector<Hypothesis> HoughSpace::findPeaks(float threshold, PeakCentre centre, const ShouldStop& should_stop) const {
  const Impl& impl = *impl_;
  LoopStop stop(should_stop);
  const VoteCaster& caster = impl.caster;
  const CategoryModel& category = caster.category();
  const std::vector<Candidate> candidates =
      impl.grid ? findCandidates(*impl.grid, threshold, centre, category.bin_size)
                : findCandidates(impl.hashed, threshold, centre, category.bin_size);
  if (candidates.empty()) return {};

  // Cast the votes again and look only at those in the bins of a candidate's cube. (Skipping
  // codewords whose votes are all too short to reach a candidate would save nothing in room
  // scans: votes reach across the objects, candidates are all over the room.)
  const CandidateCubes cubes = candidateCubes(candidates, category.bin_size, impl.inverse_bin_size);
  std::vector<Support> support;
  if (!impl.grid) {
    support = supportFromKeys(caster, impl.inverse_bin_size, cubes, stop);
  } else if (impl.vote_bins.empty()) {
    support = supportFromGrid(caster, *impl.grid, impl.inverse_bin_size, GridRanges(*impl.grid, cubes), cubes, stop);
  } else {
    support = supportFromKeptBins(caster, GridRanges(*impl.grid, cubes), impl.vote_bins, cubes, stop);
  }
  stop.check("hypothesis search");
  return suppressNearbyPeaks(hypothesesAbove(threshold, category, caster.features(), candidates, support),
                             category.bin_size);
}

std::vector<Hypothesis> suppressNearbyPeaks(std::vector<Hypothesis> peaks, float radius) {
  std::stable_sort(peaks.begin(), peaks.end(), [](const Hypothesis& a, const Hypothesis& b) { return a.score > b.score; });
  std::vector<Hypothesis> kept;
  for (auto& p : peaks) {
    const bool duplicate = std::any_of(kept.begin(), kept.end(), [&](const Hypothesis& k) {
      return (k.center - p.center).norm() < radius;
    });
    if (!duplicate) kept.push_back(std::move(p));
  }
  return kept;
}

}  // namespace ism
