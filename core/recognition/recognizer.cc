#include "core/recognition/recognizer.h"

#include <algorithm>
#include <chrono>
#include <iterator>

#include "core/common/error.h"

namespace ism {
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

// The codewords each category's votes come from: one activation serves every category with the
// global codebook; separated codebooks each need their own.
std::vector<std::vector<Activation>> activateCodewords(const Model& model, const Plan& plan, const Features& features,
                                                       const RecognitionOptions& options, StageTimings& timings) {
  const Strategy& strategy = options.strategy;
  const bool global = strategy.codebook == CodebookType::kGlobal;
  std::vector<std::vector<Activation>> activations(plan.categories.size());
  ScopedStage stage(&timings, "activate");
  for (size_t s = 0; s < plan.categories.size() && !(global && s > 0); ++s) {
    const CategoryModel& c = model.categories[static_cast<size_t>(plan.categories[s])];
    const Codebook& codebook = global ? *model.global_codebook : *c.own_codebook;
    activations[s] = codebook.activate(features.descriptors, strategy.activation);
    throwIfStopped(options.should_stop, "codeword activation");
  }
  return activations;
}

// Every planned category's peaks, one category's Hough space at a time: it is the bulk of the
// memory on a room scan. With keep_votes the votes go to result.votes as well.
std::vector<Hypothesis> findAllPeaks(const Model& model, const Plan& plan, const Features& features,
                                     const std::vector<std::vector<Activation>>& activations,
                                     const RecognitionOptions& options, RecognitionResult& result) {
  const Strategy& strategy = options.strategy;
  const bool global = strategy.codebook == CodebookType::kGlobal;
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
  return all;
}

// Ranks the hypotheses of every category against each other (Hypothesis::relativeScore) and
// sorts them into result.hypotheses and result.rejected by their box test.
void selectHypotheses(std::vector<Hypothesis> all, const RecognitionOptions& options, RecognitionResult& result) {
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

void recognizePlanned(const Model& model, const Plan& plan, const Features& features, const RecognitionOptions& options,
                      RecognitionResult& result) {
  result.keypoints = features.size();
  throwIfStopped(options.should_stop, "codeword activation");
  const auto activations = activateCodewords(model, plan, features, options, result.timings);
  selectHypotheses(findAllPeaks(model, plan, features, activations, options, result), options, result);
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
