#include "core/recognition/recognizer.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_map>

#include "core/common/error.h"

namespace ism {
namespace {

const VoteTable& votesOf(const CategoryModel& category, CodebookType type) {
  return type == CodebookType::kGlobal ? category.global_votes : category.own_votes;
}

// The cube of edge `bin_size` centred at `center`; scoreAt and findPeaks must agree on it.
bool insideCube(const Eigen::Vector3f& p, const Eigen::Vector3f& center, float half_edge) {
  return ((p - center).cwiseAbs().array() <= half_edge).all();
}

// Hough bins are addressed by their integer coordinates packed into 64 bits (21 bits each, so
// ~100 km of range at 10 cm bins) so that the sparse space is one flat hash map.
using BinKey = uint64_t;
constexpr int64_t kBinOffset = int64_t{1} << 20;
constexpr BinKey kBinMask = (BinKey{1} << 21) - 1;

Eigen::Vector3i binOf(const Eigen::Vector3f& p, float bin_size) {
  return (p / bin_size).array().floor().cast<int>();
}

BinKey keyOf(const Eigen::Vector3i& b) {
  return (static_cast<BinKey>(b.x() + kBinOffset) & kBinMask) << 42 |
         (static_cast<BinKey>(b.y() + kBinOffset) & kBinMask) << 21 | (static_cast<BinKey>(b.z() + kBinOffset) & kBinMask);
}

// Votes sorted into bins (CSR over bin ids) with the summed weight per bin.
struct HoughSpace {
  std::unordered_map<BinKey, int> id_of;
  std::vector<Eigen::Vector3i> bins;
  std::vector<float> weight;
  std::vector<int> offsets;  // bins.size() + 1
  std::vector<int> votes;    // vote indices, grouped by bin

  HoughSpace(const std::vector<Vote>& all, float bin_size) {
    std::vector<int> bin_of_vote(all.size());
    id_of.reserve(all.size() / 4 + 16);
    for (size_t i = 0; i < all.size(); ++i) {
      const Eigen::Vector3i b = binOf(all[i].position, bin_size);
      const auto [it, inserted] = id_of.try_emplace(keyOf(b), static_cast<int>(bins.size()));
      if (inserted) {
        bins.push_back(b);
        weight.push_back(0.0f);
      }
      bin_of_vote[i] = it->second;
      weight[static_cast<size_t>(it->second)] += all[i].weight;
    }
    offsets.assign(bins.size() + 1, 0);
    for (int b : bin_of_vote) ++offsets[static_cast<size_t>(b) + 1];
    for (size_t b = 0; b < bins.size(); ++b) offsets[b + 1] += offsets[b];
    votes.resize(all.size());
    std::vector<int> cursor(offsets.begin(), offsets.end() - 1);
    for (size_t i = 0; i < all.size(); ++i) votes[static_cast<size_t>(cursor[static_cast<size_t>(bin_of_vote[i])]++)] = static_cast<int>(i);
  }

  int find(const Eigen::Vector3i& b) const {
    const auto it = id_of.find(keyOf(b));
    return it == id_of.end() ? -1 : it->second;
  }

  // Calls f(neighbour id) for the existing bins among the 26 neighbours of bin `id` and itself.
  template <typename F>
  void forNeighbourhood(int id, F&& f) const {
    const Eigen::Vector3i& c = bins[static_cast<size_t>(id)];
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const int n = find(c + Eigen::Vector3i(dx, dy, dz));
          if (n >= 0) f(n);
        }
  }

  // A bin is a peak when no neighbour is heavier; equal neighbours are ordered by id so a
  // plateau yields one peak.
  bool isLocalMaximum(int id) const {
    bool maximum = true;
    const float w = weight[static_cast<size_t>(id)];
    forNeighbourhood(id, [&](int n) {
      const float wn = weight[static_cast<size_t>(n)];
      if (n != id && (wn > w || (wn == w && n < id))) maximum = false;
    });
    return maximum;
  }
};

}  // namespace

std::vector<Vote> castVotes(const Model& model, int category_index, const Features& features,
                            const std::vector<Activation>& activations, const Strategy& strategy) {
  const CategoryModel& category = model.categories.at(static_cast<size_t>(category_index));
  const VoteTable& table = votesOf(category, strategy.codebook);
  std::vector<Vote> votes;
  if (table.empty()) return votes;
  const int codewords = static_cast<int>(table.offsets.size()) - 1;
  std::vector<int> activated(features.size(), 0);  // M of each keypoint
  size_t total = 0;
  for (const auto& a : activations) {
    if (a.keypoint < 0 || static_cast<size_t>(a.keypoint) >= features.size() || a.codeword < 0 ||
        a.codeword >= codewords) {
      throw Error(ErrorCode::kInvalidInput, "castVotes: activation (keypoint " + std::to_string(a.keypoint) +
                                                ", codeword " + std::to_string(a.codeword) + ") is out of range for " +
                                                std::to_string(features.size()) + " keypoints and " +
                                                std::to_string(codewords) + " codewords of category '" +
                                                category.name + "'");
    }
    ++activated[static_cast<size_t>(a.keypoint)];
    total += table.occurrences(a.codeword);
  }
  votes.reserve(total);
  for (const auto& a : activations) {
    const size_t occurrences = table.occurrences(a.codeword);
    if (occurrences == 0) continue;
    float weight = 1.0f;
    if (strategy.weighting != VoteWeighting::kCategorization) {
      weight = 1.0f / (static_cast<float>(activated[static_cast<size_t>(a.keypoint)]) * static_cast<float>(occurrences));
      if (strategy.weighting == VoteWeighting::kActivation) weight *= 1.0f - a.distance / 2.0f;
    }
    const Eigen::Matrix3f to_scene = features.lrfs[static_cast<size_t>(a.keypoint)].transpose();
    const Eigen::Vector3f& origin = features.positions[static_cast<size_t>(a.keypoint)];
    for (uint32_t j = table.offsets[static_cast<size_t>(a.codeword)]; j < table.offsets[static_cast<size_t>(a.codeword) + 1]; ++j) {
      votes.push_back({origin + to_scene * table.vectors[j], weight, a.keypoint, category_index});
    }
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

std::vector<Hypothesis> findPeaks(const std::vector<Vote>& votes, const Features& features,
                                  const CategoryModel& category, float threshold) {
  std::vector<Hypothesis> peaks;
  if (votes.empty()) return peaks;
  const float bin_size = category.bin_size, half_edge = bin_size / 2;
  const HoughSpace hough(votes, bin_size);
  std::vector<int> last_seen(features.size(), -1);  // de-duplicates support keypoints per peak
  for (int id = 0; id < static_cast<int>(hough.bins.size()); ++id) {
    // The cube around a centre inside this bin lies within its 27 bins: cheap upper bound first.
    float bound = 0;
    hough.forNeighbourhood(id, [&](int n) { bound += hough.weight[static_cast<size_t>(n)]; });
    if (!(bound > threshold) || !hough.isLocalMaximum(id)) continue;

    Eigen::Vector3f weighted = Eigen::Vector3f::Zero();
    for (int i = hough.offsets[static_cast<size_t>(id)]; i < hough.offsets[static_cast<size_t>(id) + 1]; ++i) {
      const Vote& v = votes[static_cast<size_t>(hough.votes[static_cast<size_t>(i)])];
      weighted += v.weight * v.position;
    }
    const float bin_weight = hough.weight[static_cast<size_t>(id)];
    if (!(bin_weight > 0)) continue;
    Hypothesis h;
    h.category = category.name;
    h.threshold = threshold;
    h.center = weighted / bin_weight;
    hough.forNeighbourhood(id, [&](int n) {
      for (int i = hough.offsets[static_cast<size_t>(n)]; i < hough.offsets[static_cast<size_t>(n) + 1]; ++i) {
        const Vote& v = votes[static_cast<size_t>(hough.votes[static_cast<size_t>(i)])];
        if (!insideCube(v.position, h.center, half_edge)) continue;
        h.score += v.weight;
        if (last_seen[static_cast<size_t>(v.keypoint)] != id) {
          last_seen[static_cast<size_t>(v.keypoint)] = id;
          h.support_keypoints.push_back(features.positions[static_cast<size_t>(v.keypoint)]);
        }
      }
    });
    if (!(h.score > threshold)) continue;
    h.support = static_cast<int>(h.support_keypoints.size());
    for (const auto& p : h.support_keypoints) h.support_centroid += p;
    h.support_centroid /= static_cast<float>(h.support);
    h.box = fitOrientedBox(h.support_keypoints);
    h.passed_selection = passesBoxSelection(h.box, category.box);
    peaks.push_back(std::move(h));
  }
  std::sort(peaks.begin(), peaks.end(), [](const Hypothesis& a, const Hypothesis& b) { return a.score > b.score; });
  std::vector<Hypothesis> kept;
  for (auto& p : peaks) {
    const bool duplicate = std::any_of(kept.begin(), kept.end(), [&](const Hypothesis& k) {
      return (k.center - p.center).norm() < bin_size;
    });
    if (!duplicate) kept.push_back(std::move(p));
  }
  return kept;
}

RecognitionResult recognize(const Model& model, const Scene& scene, const RecognitionOptions& options) {
  const Strategy& strategy = options.strategy;
  if (!scene.cloud || scene.cloud->empty()) {
    throw Error(ErrorCode::kInvalidInput, "scene " + scene.source + " has no points");
  }
  std::vector<int> selected;
  if (options.categories.empty()) {
    for (size_t i = 0; i < model.categories.size(); ++i) selected.push_back(static_cast<int>(i));
  }
  for (const auto& name : options.categories) {
    const CategoryModel* c = model.find(name);
    if (c == nullptr) {
      std::string known;
      for (const auto& k : model.categories) known += (known.empty() ? "" : ", ") + k.name;
      throw Error(ErrorCode::kNotFound, "category '" + name + "' is not in the model (it has: " + known + ")");
    }
    selected.push_back(static_cast<int>(c - model.categories.data()));
  }
  if (!model.has(strategy.codebook)) {
    throw Error(ErrorCode::kInvalidInput,
                std::string("the model was trained without the ") + toString(strategy.codebook) + " codebook");
  }
  std::vector<float> thresholds;
  for (int ci : selected) {
    const CategoryModel& c = model.categories[static_cast<size_t>(ci)];
    if (options.min_score) {
      thresholds.push_back(*options.min_score);
      continue;
    }
    const auto it = c.thresholds.find({strategy.codebook, strategy.activation.strategy, strategy.weighting});
    if (it == c.thresholds.end()) {
      throw Error(ErrorCode::kInvalidInput, "the model has no threshold for category '" + c.name + "' with " +
                                                toString(strategy.codebook) + "/" +
                                                toString(strategy.activation.strategy) + "/" +
                                                toString(strategy.weighting) + "; pass a minimum score");
    }
    thresholds.push_back(it->second);
  }

  RecognitionResult result;
  FrontEndResult front = extractFeatures(scene, model.front_end, model.front_end.smoothing.enabled, &result.timings,
                                         options.should_stop);
  const Features& features = front.features;
  result.input_points = front.input_points;
  result.surface_points = front.surface ? front.surface->size() : 0;
  result.keypoints = features.size();
  throwIfStopped(options.should_stop, "codeword activation");

  // One activation serves every category with the global codebook; separated codebooks each need their own.
  std::vector<std::vector<Activation>> activations(selected.size());
  {
    ScopedStage stage(&result.timings, "activate");
    for (size_t s = 0; s < selected.size(); ++s) {
      if (strategy.codebook == CodebookType::kGlobal && s > 0) break;
      const CategoryModel& c = model.categories[static_cast<size_t>(selected[s])];
      const Codebook& codebook = strategy.codebook == CodebookType::kGlobal ? *model.global_codebook : *c.own_codebook;
      activations[s] = codebook.activate(features.descriptors, strategy.activation);
      throwIfStopped(options.should_stop, "codeword activation");
    }
  }
  const auto activationsOf = [&](size_t s) -> const std::vector<Activation>& {
    return activations[strategy.codebook == CodebookType::kGlobal ? 0 : s];
  };

  // Votes are cast and searched one category at a time so that only one category's votes (the
  // bulk of the memory: tens of millions on a room scan) are alive at once, unless kept.
  std::vector<Hypothesis> all;
  double vote_ms = 0, peak_ms = 0;
  const auto elapsed_ms = [](std::chrono::steady_clock::time_point since) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since).count();
  };
  for (size_t s = 0; s < selected.size(); ++s) {
    auto start = std::chrono::steady_clock::now();
    std::vector<Vote> votes = castVotes(model, selected[s], features, activationsOf(s), strategy);
    vote_ms += elapsed_ms(start);
    throwIfStopped(options.should_stop, "voting");
    start = std::chrono::steady_clock::now();
    auto peaks = findPeaks(votes, features, model.categories[static_cast<size_t>(selected[s])], thresholds[s]);
    std::move(peaks.begin(), peaks.end(), std::back_inserter(all));
    peak_ms += elapsed_ms(start);
    throwIfStopped(options.should_stop, "hypothesis search");
    if (options.keep_votes) std::move(votes.begin(), votes.end(), std::back_inserter(result.votes));
  }
  result.timings.add("vote", vote_ms);
  result.timings.add("hypotheses", peak_ms);

  {
    ScopedStage stage(&result.timings, "select");
    std::stable_sort(all.begin(), all.end(), [](const Hypothesis& a, const Hypothesis& b) { return a.score > b.score; });
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
  return result;
}

}  // namespace ism
