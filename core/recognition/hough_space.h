#pragma once
// The Hough space: one category's votes summed in bins of edge bin_size, and the peak search
// over them. A peak is a bin that is a local maximum of its 26 neighbours whose cube of votes
// around their weighted mean scores above the threshold; nearby weaker peaks are suppressed.
#include <cstddef>
#include <memory>
#include <vector>

#include "core/codebook/codebook.h"
#include "core/common/types.h"
#include "core/model/model.h"
#include "core/recognition/hypothesis.h"
#include "core/recognition/voting.h"

namespace ism {

// Where a peak's cube is centred in its bin, a local maximum of its 26 neighbours.
enum class PeakCentre {
  // At the weighted mean of the bin's own votes, as the seed: on an object longer than a bin its
  // votes run along a ridge of bins, and which bin of the ridge wins and where in it the votes
  // fell move with any change of the scene far below the sensor's noise.
  kBin,
  // At the weighted mean of the votes in the bin and its 26 neighbours, kept inside the bin (so
  // the cube stays within them): one step of the mean-shift search that ISM places its
  // hypotheses with (Leibe, Leonardis and Schiele, "Robust object detection with interleaved
  // categorization and segmentation", IJCV 2008), with a kernel three bins wide, taken from the
  // bins' sums without casting the votes again. The default: over three pairs of training draws
  // and nine draws of the clouds' up it finds more objects with fewer false answers, chairs most
  // (docs/EVALUATION.md, "A peak centred on its 27 bins' votes").
  kNeighbourhood,
};
const char* toString(PeakCentre centre);

// One category's sparse 3D Hough space for one scene. The votes are accumulated bin by bin
// (weight and weighted position) as they are cast, in parallel over keypoints, and never
// stored: a room scan casts tens of millions. Results do not depend on thread scheduling; a
// different thread count changes the (double) sums only in their last bits.
// Keeps references to its arguments, which must outlive it.
class HoughSpace {
 public:
  // The bins are kept in blocks of 4 x 4 x 4 found through a table over the box that holds every
  // vote (8 bytes per block of the box, 2 MB per thread at this limit; 2 KB per block with votes)
  // when the box has at most this many bins and no more blocks than votes, else in a hash map.
  // Past the limit (a scan hundreds of metres across, centimetre bins over a building) the table
  // would outweigh the occupied bins.
  static constexpr size_t kMaxGridBins = size_t{1} << 24;
  // Up to this many votes, gridded bins also keep each vote's bin (4 bytes a vote, 64 MB at the
  // limit): findPeaks then reads them instead of casting every vote again, and places only the
  // votes near a candidate, which costs less than casting them all again.
  static constexpr size_t kMaxKeptVoteBins = size_t{1} << 24;

  // Throws Error(kInvalidInput) for an activation outside the features or the vote table.
  // `max_grid_bins` lowers the limit, 0 always hashes the bins; `max_kept_vote_bins` likewise
  // (tests). The results do not depend on either. `should_stop` is polled while votes are cast
  // (from several threads at once); Error(kCancelled) when it says stop.
  HoughSpace(const Model& model, int category_index, const Features& features,
             const std::vector<Activation>& activations, const Strategy& strategy,
             size_t max_grid_bins = kMaxGridBins, size_t max_kept_vote_bins = kMaxKeptVoteBins,
             const ShouldStop& should_stop = {});
  ~HoughSpace();
  HoughSpace(const HoughSpace&) = delete;
  HoughSpace& operator=(const HoughSpace&) = delete;

  // Every bin that is a local maximum of its 26 neighbours (ties: the lower bin coordinates
  // win), centred as `centre` says and scored like scoreAt() there, when the score exceeds
  // `threshold`; within bin_size of a better one it is dropped. Best first.
  // The score and support are found by casting the votes again and keeping only those that land
  // in a bin a peak's cube meets. Each peak's box is fitted and checked (box_selection.h).
  // `should_stop` as for the constructor.
  std::vector<Hypothesis> findPeaks(float threshold, PeakCentre centre = PeakCentre::kBin,
                                    const ShouldStop& should_stop = {}) const;

  const VoteCaster& caster() const;
  size_t votes() const;  // cast into the space
  size_t bins() const;   // occupied
  bool gridded() const;  // the bins are in a grid rather than a hash map
  bool keptVoteBins() const;  // the grid also has every vote's bin

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Peaks best first (by score, stable), each dropped when it lies within `radius` of a better
// peak that was kept.
std::vector<Hypothesis> suppressNearbyPeaks(std::vector<Hypothesis> peaks, float radius);

}  // namespace ism
