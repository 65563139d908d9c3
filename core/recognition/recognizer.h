#pragma once
// Recognition: features -> codeword activations -> weighted votes in a 3D Hough space per
// category -> every local maximum above the threshold -> box selection -> hypotheses.
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/common/types.h"
#include "core/frontend/frontend.h"
#include "core/model/model.h"

namespace ism {

struct RecognitionOptions {
  Strategy strategy;                    // codebook type, activation, weighting: per call
  std::vector<std::string> categories;  // empty = every category of the model
  // Overrides the model's leave-one-out threshold for the chosen strategy when set.
  std::optional<float> min_score;
  int max_hypotheses = 0;               // 0 = no limit; best first (Hypothesis::relativeScore)
  bool box_selection = true;            // false: keep hypotheses that fail the box test too
  bool return_keypoints = false;        // fill Hypothesis::support_keypoints
  bool keep_votes = false;              // fill RecognitionResult::votes (debug PLY)
  ShouldStop should_stop;               // polled between stages and in long loops
};

struct Hypothesis {
  std::string category;
  float score = 0;       // summed vote weight around the centre
  float threshold = 0;   // the threshold the score was compared with
  // How far above its category's threshold: what ranks hypotheses of different categories
  // against each other, since raw scores are not comparable across categories (LW and AW
  // scores scale with 1/|Occ|, which differs per category's vote table).
  float relativeScore() const { return threshold > 0 ? score / threshold : score; }
  Eigen::Vector3f center = Eigen::Vector3f::Zero();  // weighted mean of the votes in the peak
  OrientedBox box;       // PCA box of the supporting keypoints
  int support = 0;       // keypoints that voted into the peak
  Eigen::Vector3f support_centroid = Eigen::Vector3f::Zero();
  bool passed_selection = true;  // box volume within range and longest edge below the maximum
  std::vector<Eigen::Vector3f> support_keypoints;  // when asked for
};

struct Vote {
  Eigen::Vector3f position;  // where the vote lands (scene frame)
  float weight;
  int keypoint;              // index into Features
  int category;              // index into Model::categories
};

struct RecognitionResult {
  std::vector<Hypothesis> hypotheses;  // passed selection, best first
  std::vector<Hypothesis> rejected;    // above threshold but failed box selection
  StageTimings timings;
  size_t input_points = 0;
  size_t surface_points = 0;
  size_t keypoints = 0;
  std::vector<Eigen::Vector3f> keypoint_positions;  // when keep_votes
  std::vector<Vote> votes;                          // when keep_votes
};

// Throws Error(kNotFound) for an unknown category, Error(kInvalidInput) for a strategy the
// model was not trained for (e.g. separated codebook missing) or a scene with no points left.
RecognitionResult recognize(const Model& model, const Scene& scene, const RecognitionOptions& options);

// recognize() after the front end: activation, voting, peak search and box selection on
// already extracted features (evaluation runs the front end once and every strategy on it).
// Same errors as recognize() except for the scene; the point counts of the result stay 0.
RecognitionResult recognizeFeatures(const Model& model, const Features& features, const RecognitionOptions& options);

// --- The stages, exposed for training (leave-one-out), evaluation and tests. ---

// Votes of one category's ISM for already extracted features, materialised (debug output,
// leave-one-out scores); recognition itself accumulates them into a HoughSpace instead.
std::vector<Vote> castVotes(const Model& model, int category_index, const Features& features,
                            const std::vector<Activation>& activations, const Strategy& strategy);

// Summed weight of the votes inside the cube of edge bin_size centred at `center`: the score a
// hypothesis there would get (used for the leave-one-out thresholds).
float scoreAt(const std::vector<Vote>& votes, const Eigen::Vector3f& center, float bin_size);

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
  // votes near a candidate. On a Kinect frame that took a quarter off its time (20 -> 15 ms on one
  // thread), for 1 ms more voting.
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
  // win), centred at the weighted mean of its votes and scored like scoreAt() there, when the
  // score exceeds `threshold`; within bin_size of a better one it is dropped. Best first.
  // The score and support are found by casting the votes again and keeping only those that land
  // in a bin a peak's cube meets.
  // `should_stop` as for the constructor.
  std::vector<Hypothesis> findPeaks(float threshold, const ShouldStop& should_stop = {}) const;

  size_t votes() const;  // cast into the space
  size_t bins() const;   // occupied
  bool gridded() const;  // the bins are in a grid rather than a hash map
  bool keptVoteBins() const;  // the grid also has every vote's bin

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// PCA oriented box of points.
OrientedBox fitOrientedBox(const std::vector<Eigen::Vector3f>& points);

bool passesBoxSelection(const OrientedBox& box, const BoxStats& stats);

}  // namespace ism
