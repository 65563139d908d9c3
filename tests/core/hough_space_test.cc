#include "core/recognition/hough_space.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <tuple>

#include "core/recognition/voting.h"
#include "tests/common/hand_made_votes.h"

namespace ism {
namespace {

using namespace ism::testing;

// Two hand-made objects in one scene: 30 keypoints voting for `a`, then 20 voting for `b`,
// each keypoint with its own codeword.
HandMadeObject twoObjects(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  HandMadeObject both = handMadeObject(a, 30, 0, 0.02f);
  const HandMadeObject second = handMadeObject(b, 20, 30, 0.02f);
  Features& f = both.features;
  f.positions.insert(f.positions.end(), second.features.positions.begin(), second.features.positions.end());
  f.lrfs.insert(f.lrfs.end(), second.features.lrfs.begin(), second.features.lrfs.end());
  both.votes.insert(both.votes.end(), second.votes.begin(), second.votes.end());
  both.activations.insert(both.activations.end(), second.activations.begin(), second.activations.end());
  return both;
}

TEST(FindPeaks, TwoSeparatedClustersGiveTwoHypotheses) {
  const Eigen::Vector3f a(0, 0, 0.5f), b(1.5f, 0.3f, 0.5f);
  const HandMadeObject scene = twoObjects(a, b);
  const Features& f = scene.features;
  const auto& activations = scene.activations;
  const Model m = modelWithVotes(scene.votes);
  const Strategy cw = strategy(VoteWeighting::kCategorization);
  const HoughSpace hough(m, 0, f, activations, cw);
  EXPECT_EQ(hough.votes(), 50u);
  const auto peaks = hough.findPeaks(5.0f);
  ASSERT_EQ(peaks.size(), 2u);
  EXPECT_LT((peaks[0].center - a).norm(), 0.05f);
  EXPECT_LT((peaks[1].center - b).norm(), 0.05f);
  EXPECT_GE(peaks[0].score, peaks[1].score);
  EXPECT_EQ(peaks[1].support, 20);
  const auto votes = castVotes(m, 0, f, activations, cw);
  for (const auto& p : peaks) {
    EXPECT_FLOAT_EQ(p.score, scoreAt(votes, p.center, m.categories[0].bin_size));
    EXPECT_GT(p.score, p.threshold);
  }
  // A threshold above the weaker cluster keeps only the stronger one.
  EXPECT_EQ(hough.findPeaks(25.0f).size(), 1u);
}

TEST(FindPeaks, NoVotesNoHypotheses) {
  const Model m = modelWithVotes({{Eigen::Vector3f::Zero()}});
  const HoughSpace hough(m, 0, Features{}, {}, strategy(VoteWeighting::kCategorization));
  EXPECT_EQ(hough.bins(), 0u);
  EXPECT_TRUE(hough.findPeaks(0.0f).empty());
}

// The definition of the peak search, written for clarity: every vote in a std::map of bins,
// every score by brute force over all votes.
std::vector<Hypothesis> referencePeaks(const std::vector<Vote>& votes, const Features& features,
                                       const CategoryModel& category, float threshold,
                                       PeakCentre centre = PeakCentre::kBin) {
  using Bin = std::tuple<int, int, int>;
  struct Sum {
    double weight = 0;
    Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
  };
  const float s = category.bin_size, inverse = 1.0f / s;  // a vote's bin: floor(p * (1 / bin size))
  std::map<Bin, Sum> bins;  // ordered by coordinates: the tie-break and the candidate order
  for (const auto& v : votes) {
    const auto bin = [&](float x) { return static_cast<int>(std::floor(x * inverse)); };
    Sum& sum = bins[{bin(v.position.x()), bin(v.position.y()), bin(v.position.z())}];
    sum.weight += v.weight;
    sum.weighted += v.weight * v.position.cast<double>();
  }
  std::vector<Hypothesis> peaks;
  for (const auto& [bin, sum] : bins) {
    if (!(sum.weight > 0)) continue;
    double bound = 0;
    Eigen::Vector3d around = Eigen::Vector3d::Zero();
    bool maximum = true;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const Bin n{std::get<0>(bin) + dx, std::get<1>(bin) + dy, std::get<2>(bin) + dz};
          const auto it = bins.find(n);
          if (it == bins.end()) continue;
          bound += it->second.weight;
          around += it->second.weighted;
          if (it->second.weight > sum.weight || (it->second.weight == sum.weight && n < bin)) maximum = false;
        }
    if (!maximum || !(bound > threshold)) continue;
    Hypothesis h;
    h.category = category.name;
    h.threshold = threshold;
    h.center = (sum.weighted / sum.weight).cast<float>();
    if (centre == PeakCentre::kNeighbourhood) {
      // The 27 bins' mean, clamped into the bin itself.
      const Eigen::Vector3f lo = Eigen::Vector3f(std::get<0>(bin), std::get<1>(bin), std::get<2>(bin)) * s;
      const Eigen::Vector3f mean = (around / bound).cast<float>();
      for (int a = 0; a < 3; ++a) h.center[a] = std::clamp(mean[a], lo[a], lo[a] + s);
    }
    h.score = scoreAt(votes, h.center, s);
    if (!(h.score > threshold)) continue;
    std::vector<int> support;
    for (const auto& v : votes) {
      if (((v.position - h.center).cwiseAbs().array() <= s / 2).all()) support.push_back(v.keypoint);
    }
    std::sort(support.begin(), support.end());
    support.erase(std::unique(support.begin(), support.end()), support.end());
    for (int k : support) h.support_keypoints.push_back(features.positions[static_cast<size_t>(k)]);
    h.support = static_cast<int>(support.size());
    peaks.push_back(h);
  }
  std::stable_sort(peaks.begin(), peaks.end(), [](const Hypothesis& a, const Hypothesis& b) { return a.score > b.score; });
  std::vector<Hypothesis> kept;
  for (const auto& p : peaks) {
    if (std::none_of(kept.begin(), kept.end(), [&](const Hypothesis& k) { return (k.center - p.center).norm() < s; })) {
      kept.push_back(p);
    }
  }
  return kept;
}

// Random scene: three objects whose keypoints vote for their centres, and clutter keypoints
// activating codewords with random votes; enough keypoints to split them between threads.
HandMadeObject randomScene(std::mt19937& rng) {
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f), distance(0.0f, 0.6f);
  HandMadeObject scene;
  for (const Eigen::Vector3f& center : {Eigen::Vector3f(0, 0, 0.5f), Eigen::Vector3f(1.2f, 0.4f, 0.4f),
                                        Eigen::Vector3f(-0.8f, 1.5f, 0.45f)}) {
    const HandMadeObject o = handMadeObject(center, 150, static_cast<int>(scene.votes.size()), 0.05f);
    scene.features.positions.insert(scene.features.positions.end(), o.features.positions.begin(), o.features.positions.end());
    scene.features.lrfs.insert(scene.features.lrfs.end(), o.features.lrfs.begin(), o.features.lrfs.end());
    scene.votes.insert(scene.votes.end(), o.votes.begin(), o.votes.end());
    scene.activations.insert(scene.activations.end(), o.activations.begin(), o.activations.end());
  }
  const int object_codewords = static_cast<int>(scene.votes.size()), clutter_codewords = 40;
  for (int c = 0; c < clutter_codewords; ++c) {
    std::vector<Eigen::Vector3f> list;
    for (int j = 0; j < 30; ++j) list.emplace_back(unit(rng), unit(rng), unit(rng));
    scene.votes.push_back(list);
  }
  // Object keypoints also activate a clutter codeword; clutter keypoints one to three of them.
  for (int k = 0; k < object_codewords; ++k) scene.activations.push_back({k, object_codewords + k % clutter_codewords, distance(rng)});
  for (int k = object_codewords; k < 2000; ++k) {
    scene.features.positions.emplace_back(2 * unit(rng), 2 * unit(rng), 0.5f + 0.5f * unit(rng));
    scene.features.lrfs.push_back(Eigen::Quaternionf::UnitRandom().toRotationMatrix());
    const int activated = 1 + k % 3;
    for (int a = 0; a < activated; ++a) {
      scene.activations.push_back({k, object_codewords + static_cast<int>(rng() % clutter_codewords), distance(rng)});
    }
  }
  return scene;
}

// Thresholds low enough for clutter maxima (CW: many equal bin weights, so the tie rule counts).
const std::pair<VoteWeighting, float> kRandomSceneThresholds[] = {
    {VoteWeighting::kCategorization, 7.0f}, {VoteWeighting::kLocalization, 0.15f}, {VoteWeighting::kActivation, 0.12f}};

// Every way of keeping the bins: the grid over the votes' box with each vote's bin (the default
// here), the grid alone (votes cast again to find the peaks' support), and the hash map.
struct BinStorage {
  const char* name;
  size_t max_grid_bins, max_kept_vote_bins;
};
constexpr BinStorage kBinStorages[] = {{"grid with vote bins", HoughSpace::kMaxGridBins, HoughSpace::kMaxKeptVoteBins},
                                       {"grid", HoughSpace::kMaxGridBins, 0},
                                       {"hashed", 0, 0}};

TEST(FindPeaks, MatchesTheReferenceOnRandomData) {
  std::mt19937 rng(7);
  const HandMadeObject scene = randomScene(rng);
  const Model m = modelWithVotes(scene.votes);
  const CategoryModel& category = m.categories[0];
  for (auto [weighting, threshold] : kRandomSceneThresholds) {
    for (const BinStorage& storage : kBinStorages) {
      for (PeakCentre centre : {PeakCentre::kBin, PeakCentre::kNeighbourhood}) {
        SCOPED_TRACE(std::string(toString(weighting)) + " " + storage.name + " " + toString(centre));
        const size_t max_grid_bins = storage.max_grid_bins;
        const Strategy st = strategy(weighting);
        const auto votes = castVotes(m, 0, scene.features, scene.activations, st);
        const auto expected = referencePeaks(votes, scene.features, category, threshold, centre);
        const HoughSpace hough(m, 0, scene.features, scene.activations, st, max_grid_bins, storage.max_kept_vote_bins);
        EXPECT_EQ(hough.gridded(), max_grid_bins > 0);
        EXPECT_EQ(hough.keptVoteBins(), storage.max_kept_vote_bins > 0);
        EXPECT_EQ(hough.votes(), votes.size());
        const auto actual = hough.findPeaks(threshold, centre);
        ASSERT_GE(expected.size(), 10u);  // the objects and clutter maxima
        ASSERT_EQ(actual.size(), expected.size());
        for (size_t i = 0; i < expected.size(); ++i) {
          SCOPED_TRACE(i);
          // Matched by centre, not by rank: two peaks whose scores differ only in the last bits
          // (the reference sums its votes in another order) may swap places.
          size_t match = 0;
          for (size_t j = 1; j < actual.size(); ++j) {
            if ((actual[j].center - expected[i].center).norm() < (actual[match].center - expected[i].center).norm()) match = j;
          }
          const Hypothesis& a = actual[match];
          EXPECT_LT((a.center - expected[i].center).norm(), 1e-5f);
          EXPECT_NEAR(a.score, expected[i].score, 1e-5f * expected[i].score);
          EXPECT_EQ(a.support_keypoints, expected[i].support_keypoints);
          EXPECT_EQ(a.support, expected[i].support);
          EXPECT_EQ(a.category, category.name);
        }
        // Same input, same answer: thread scheduling must not leak into the sums.
        const auto again = HoughSpace(m, 0, scene.features, scene.activations, st, max_grid_bins,
                                      storage.max_kept_vote_bins).findPeaks(threshold, centre);
        ASSERT_EQ(again.size(), actual.size());
        for (size_t i = 0; i < again.size(); ++i) {
          EXPECT_EQ(again[i].score, actual[i].score);
          EXPECT_EQ(again[i].center, actual[i].center);
        }
      }
    }
  }
}

void expectSameHypotheses(const std::vector<Hypothesis>& a, const std::vector<Hypothesis>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(a[i].category, b[i].category);
    EXPECT_EQ(a[i].score, b[i].score);
    EXPECT_EQ(a[i].center, b[i].center);
    EXPECT_EQ(a[i].support, b[i].support);
    EXPECT_EQ(a[i].support_keypoints, b[i].support_keypoints);
    EXPECT_EQ(a[i].box.center, b[i].box.center);
    EXPECT_EQ(a[i].passed_selection, b[i].passed_selection);
  }
}

// The grid must hold every vote, also of local reference frames that are not rotations (the
// bound on a vote's reach then takes the frame's column norms), and sum the bins exactly like the
// hash map: the same votes in the same order, so the same bits.
TEST(FindPeaks, GridAndHashedBinsGiveTheSameHypotheses) {
  std::mt19937 rng(11);
  HandMadeObject scene = randomScene(rng);
  std::uniform_real_distribution<float> scale(0.5f, 2.0f);
  for (size_t k = 0; k < scene.features.size(); k += 3) {
    scene.features.lrfs[k] = scene.features.lrfs[k] * Eigen::Vector3f(scale(rng), scale(rng), scale(rng)).asDiagonal();
    scene.features.lrfs[k](0, 1) += 0.3f;  // no longer orthogonal either
  }
  const Model m = modelWithVotes(scene.votes);
  for (auto [weighting, threshold] : kRandomSceneThresholds) {
    SCOPED_TRACE(toString(weighting));
    const Strategy st = strategy(weighting);
    const HoughSpace grid(m, 0, scene.features, scene.activations, st);
    const HoughSpace hashed(m, 0, scene.features, scene.activations, st, 0);
    const HoughSpace cast_again(m, 0, scene.features, scene.activations, st, HoughSpace::kMaxGridBins, 0);
    ASSERT_TRUE(grid.gridded() && grid.keptVoteBins());
    ASSERT_FALSE(hashed.gridded());
    ASSERT_TRUE(cast_again.gridded() && !cast_again.keptVoteBins());
    EXPECT_EQ(grid.bins(), hashed.bins());
    const auto peaks = grid.findPeaks(threshold);
    EXPECT_GE(peaks.size(), 10u);
    expectSameHypotheses(peaks, hashed.findPeaks(threshold));
    // A vote's position is computed again only where it lands near a candidate: the same bits.
    expectSameHypotheses(peaks, cast_again.findPeaks(threshold));
  }
}

// Keypoints a kilometre apart: the votes' box has 10^9 bins, far more than kMaxGridBins and than
// there are votes, so the bins are hashed and only the occupied ones kept.
TEST(FindPeaks, FarApartKeypointsFallBackToHashedBins) {
  const Eigen::Vector3f a(0, 0, 0.5f), b(1000.0f, 1000.0f, 0.5f);
  const HandMadeObject scene = twoObjects(a, b);
  const Features& f = scene.features;
  const auto& activations = scene.activations;
  const Model m = modelWithVotes(scene.votes);
  const HoughSpace hough(m, 0, f, activations, strategy(VoteWeighting::kCategorization));
  EXPECT_FALSE(hough.gridded());
  const auto peaks = hough.findPeaks(5.0f);
  ASSERT_EQ(peaks.size(), 2u);
  EXPECT_LT((peaks[0].center - a).norm(), 0.05f);
  EXPECT_LT((peaks[1].center - b).norm(), 0.05f);
  EXPECT_EQ(peaks[0].support, 30);
  EXPECT_EQ(peaks[1].support, 20);
}

// Votes on the faces of the cube around a peak count, votes a float step outside do not, also
// when they fall in other bins than the peak's (only the bins the cube meets are looked at).
TEST(FindPeaks, VotesOnTheFacesOfTheCubeCount) {
  // Keypoints at the origin with identity frames: each vote lands exactly at its stored vector.
  // Bins of 0.5 m: the peak's bin [0, 0.5)^3 holds ten votes at its centre, so the cube is
  // [0, 0.5]^3, whose upper faces lie in the next bins.
  // One float step beyond the faces as seen from the centre (steps of 2^-25 around 0.25, the
  // distance to a face; 2^-24 around 0.5).
  const float outside_high = std::nextafter(0.5f, 1.0f), outside_low = -0x1p-25f;
  std::vector<std::vector<Eigen::Vector3f>> votes(10, {Eigen::Vector3f(0.25f, 0.25f, 0.25f)});
  for (const Eigen::Vector3f& v : {Eigen::Vector3f(0.5f, 0.25f, 0.25f), Eigen::Vector3f(0.0f, 0.5f, 0.5f),
                                   Eigen::Vector3f(0.5f, 0.5f, 0.5f)}) {
    votes.push_back({v});  // on a face, an edge, a corner: inside
  }
  for (const Eigen::Vector3f& v : {Eigen::Vector3f(outside_high, 0.25f, 0.25f), Eigen::Vector3f(0.25f, outside_low, 0.25f),
                                   Eigen::Vector3f(0.5f, 0.5f, outside_high)}) {
    votes.push_back({v});
  }
  Features f;
  std::vector<Activation> activations;
  for (size_t k = 0; k < votes.size(); ++k) {
    f.positions.push_back(Eigen::Vector3f::Zero());
    f.lrfs.push_back(Eigen::Matrix3f::Identity());
    activations.push_back({static_cast<int>(k), static_cast<int>(k), 0.0f});
  }
  const Model m = modelWithVotes(votes, 0.5f);
  const Strategy cw = strategy(VoteWeighting::kCategorization);
  const auto cast = castVotes(m, 0, f, activations, cw);
  for (const BinStorage& storage : kBinStorages) {
    SCOPED_TRACE(storage.name);
    const HoughSpace hough(m, 0, f, activations, cw, storage.max_grid_bins, storage.max_kept_vote_bins);
    EXPECT_EQ(hough.gridded(), storage.max_grid_bins > 0);
    const auto peaks = hough.findPeaks(5.0f);
    ASSERT_EQ(peaks.size(), 1u);
    EXPECT_EQ(peaks[0].center, Eigen::Vector3f(0.25f, 0.25f, 0.25f));
    EXPECT_EQ(peaks[0].score, 13.0f);
    EXPECT_EQ(peaks[0].support, 13);
    EXPECT_EQ(peaks[0].score, scoreAt(cast, peaks[0].center, 0.5f));
  }
}

// Best first; a peak within the radius of a better one that was kept goes, whatever its score.
// Equal scores keep their order.
TEST(SuppressNearbyPeaks, KeepsTheBestOfPeaksCloserThanTheRadius) {
  const auto peak = [](const char* name, float score, const Eigen::Vector3f& center) {
    Hypothesis h;
    h.category = name;
    h.score = score;
    h.center = center;
    return h;
  };
  const std::vector<Hypothesis> kept = suppressNearbyPeaks(
      {peak("a", 1.0f, {0, 0, 0}), peak("b", 3.0f, {0.05f, 0, 0}), peak("c", 2.0f, {0.3f, 0, 0}),
       peak("d", 2.0f, {0.3f, 0.09f, 0})},
      0.1f);
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_EQ(kept[0].category, "b");
  EXPECT_EQ(kept[1].category, "c");
}

}  // namespace
}  // namespace ism
