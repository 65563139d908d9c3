#include "core/recognition/recognizer.h"

#include <algorithm>
#include <cmath>
#include <chrono>
#include <iterator>

#include "core/common/error.h"
#include "core/gravity/viewpoint.h"
#include "core/recognition/suppression.h"
#include "core/recognition/upright_boxes.h"
#include "core/recognition/verification.h"

namespace ism {

const char* toString(RecognitionPreset p) { return p == RecognitionPreset::kDefault ? "default" : "seed"; }

RecognitionPreset parseRecognitionPreset(const std::string& s) {
  if (s == "default") return RecognitionPreset::kDefault;
  if (s == "seed") return RecognitionPreset::kSeed;
  throw Error(ErrorCode::kInvalidInput, "unknown preset '" + s + "' (expected default or seed)");
}

namespace {

// Peaks less likely than this are not looked at, whatever min_confidence asks.
constexpr float kLowestConfidence = 0.01f;

// A category's confidence for a peak: its calibration, or without one (models trained before
// calibration) 1 - 2^-(score / threshold), 0.5 at the leave-one-out threshold.
struct ConfidenceCurve {
  std::optional<Calibration> calibration;
  std::optional<Calibration> cloud_calibration;  // replaces `calibration` for unorganized scenes
  float threshold = 0;
  float operator()(const Hypothesis& peak) const {
    if (calibration) {
      return peak.verification ? calibration->confidence(peak.score, peak.support, peak.verification->fit(),
                                                         peak.verification->profile_distance)
                               : calibration->confidence(peak.score, peak.support);
    }
    return threshold > 0 ? 1.0f - std::exp2(-peak.score / threshold) : 1.0f;
  }
  // The most a peak can reach once verified (or left unverified): with the fit and the profile
  // distance at whichever end raises confidence.
  float best(const Hypothesis& peak) const {
    if (!calibration) return (*this)(peak);
    return std::max(calibration->confidence(peak.score, peak.support),
                    calibration->confidence(peak.score, peak.support, calibration->d > 0 ? 1.0f : 0.0f,
                                            calibration->e < 0 ? 0.0f : 2.0f));
  }
  // The lowest score a peak of at least `confidence` can have: what the peak search starts from.
  float lowestScore(float confidence) const {
    if (calibration) return calibration->min_score;
    return -threshold * std::log2(1.0f - confidence);
  }
};

// The categories to search and their thresholds, checked before any work is done.
struct Plan {
  std::vector<int> categories;  // indices into Model::categories
  std::vector<float> thresholds;
  std::vector<ConfidenceCurve> confidence;
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
  if (!(options.min_confidence >= 0 && options.min_confidence <= 0.99f)) {
    throw Error(ErrorCode::kInvalidInput,
                "min_confidence " + std::to_string(options.min_confidence) + " is not in [0, 0.99]");
  }
  for (int ci : plan.categories) {
    const CategoryModel& c = model.categories[static_cast<size_t>(ci)];
    const auto it = c.thresholds.find({strategy.codebook, strategy.activation.strategy, strategy.weighting});
    const bool calibrated = c.calibration && strategy.codebook == CodebookType::kGlobal &&
                            strategy.activation.strategy == model.trained_knn.strategy &&
                            strategy.activation.k == model.trained_knn.k &&
                            strategy.weighting == VoteWeighting::kLocalization;
    ConfidenceCurve curve;
    if (calibrated) curve.calibration = c.calibration, curve.cloud_calibration = c.cloud_calibration;
    if (it != c.thresholds.end()) curve.threshold = it->second;
    plan.confidence.push_back(curve);
    if (options.min_score) {
      plan.thresholds.push_back(*options.min_score);
      continue;
    }
    if (it == c.thresholds.end()) {
      throw Error(ErrorCode::kInvalidInput, "the model has no threshold for category '" + c.name + "' with " +
                                                toString(strategy.codebook) + "/" +
                                                toString(strategy.activation.strategy) + "/" +
                                                toString(strategy.weighting) + "; pass a minimum score");
    }
    plan.thresholds.push_back(options.preset == RecognitionPreset::kSeed
                                  ? it->second
                                  : curve.lowestScore(std::max(options.min_confidence, kLowestConfidence)));
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

// Whether a peak's centre is at a height above the floor the category's training objects had
// theirs, give or take the priors' slack.
bool withinHeightPrior(const Hypothesis& peak, const CategoryModel& category, const Features& features, float slack) {
  if (!features.gravity || !features.gravity->hasFloor()) return true;
  return withinTrainingRange(category, [](const TrainingObject& o) { return o.center_height; },
                             features.gravity->height(peak.center), slack);
}

// Every planned category's peaks, one category's Hough space at a time: it is the bulk of the
// memory on a room scan. With keep_votes the votes go to result.votes as well. In the default
// preset each peak gets its confidence and upright box, and peaks outside the category's height
// prior go to result.rejected.
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
    const CategoryModel& category = model.categories[static_cast<size_t>(plan.categories[s])];
    for (auto& peak : peaks) {
      peak.confidence = plan.confidence[s](peak);
      if (options.preset == RecognitionPreset::kSeed) {
        all.push_back(std::move(peak));
        continue;
      }
      if (plan.confidence[s].best(peak) < std::max(options.min_confidence, kLowestConfidence)) continue;
      estimateUprightBox(hough.caster(), category.bin_size / 2, peak);
      peak.passed_selection = withinHeightPrior(peak, category, features, priorSlack(model, category));
      (peak.passed_selection ? all : result.rejected).push_back(std::move(peak));
    }
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

// Default preset: each category's peaks merged to one per object, then verified against the
// scene, and their confidences made again with the fit. A hypothesis whose agreeing surface is
// mostly another's of its category (their boxes overlap too little to be merged) is dropped. The
// scene's checks (scene_checks.h) send the hypotheses they contradict to result.rejected and mark
// the ones they refute, which are rejected after the answers per object are chosen
// (selectHypotheses).
void verifyPeaks(const Model& model, const Plan& plan, const Features& features, const Scene& scene,
                 const RecognitionOptions& options, std::vector<Hypothesis>& all, RecognitionResult& result) {
  ScopedStage stage(&result.timings, "verify");
  const Eigen::Matrix3f to_gravity = features.gravity ? features.gravity->toGravity() : Eigen::Matrix3f::Identity();
  std::vector<Hypothesis> verified;
  const VerificationScene view = makeVerificationScene(scene, features.gravity, options.verification);
  for (size_t s = 0; s < plan.categories.size(); ++s) {
    const std::string& name = model.categories[static_cast<size_t>(plan.categories[s])].name;
    std::vector<Hypothesis> own;
    for (auto& h : all) {
      if (h.category == name) own.push_back(std::move(h));
    }
    if (options.one_answer_per_object) own = suppressOverlaps(std::move(own), to_gravity, options.suppression);
    verifyHypotheses(view, model, own, options.verification, options.should_stop);
    const CategoryModel& category = model.categories[static_cast<size_t>(plan.categories[s])];
    const SceneChecks checks(model, category, options.scene_checks);
    for (auto& h : own) {
      if (options.one_answer_per_object && h.verification && h.verification->duplicate()) continue;
      h.confidence = plan.confidence[s](h);
      if (h.confidence < std::max(options.min_confidence, kLowestConfidence)) continue;
      const SceneVerdict verdict = checks(view, h, to_gravity);
      if (verdict == SceneVerdict::kRejected) {
        h.passed_selection = false;
        result.rejected.push_back(std::move(h));
        continue;
      }
      h.refuted = verdict == SceneVerdict::kRefuted;
      verified.push_back(std::move(h));
    }
  }
  all = std::move(verified);
}

// The seed's preset ranks the hypotheses of every category against each other by
// Hypothesis::relativeScore and sorts them into result.hypotheses and result.rejected by their
// box test. The default preset keeps one answer per object and the confident ones, best first.
void selectHypotheses(std::vector<Hypothesis> all, const Features& features, const RecognitionOptions& options,
                      RecognitionResult& result) {
  ScopedStage stage(&result.timings, "select");
  if (options.preset == RecognitionPreset::kSeed) {
    std::stable_sort(all.begin(), all.end(),
                     [](const Hypothesis& a, const Hypothesis& b) { return a.relativeScore() > b.relativeScore(); });
  } else {
    const Eigen::Matrix3f to_gravity = features.gravity ? features.gravity->toGravity() : Eigen::Matrix3f::Identity();
    if (options.one_answer_per_object) {
      all = suppressOverlaps(std::move(all), to_gravity, options.suppression);
    } else {
      std::stable_sort(all.begin(), all.end(),
                       [](const Hypothesis& a, const Hypothesis& b) { return a.confidence > b.confidence; });
    }
    all.erase(std::remove_if(all.begin(), all.end(),
                             [&](const Hypothesis& h) { return h.confidence < options.min_confidence; }),
              all.end());
    const auto refuted = std::stable_partition(all.begin(), all.end(), [](const Hypothesis& h) { return !h.refuted; });
    for (auto h = refuted; h != all.end(); ++h) {
      h->passed_selection = false;
      result.rejected.push_back(std::move(*h));
    }
    all.erase(refuted, all.end());
  }
  for (auto& rejected : result.rejected) {
    if (!options.return_keypoints) rejected.support_keypoints = {};
  }
  for (auto& h : all) {
    if (!options.return_keypoints) h.support_keypoints = {};
    const bool selected = options.preset == RecognitionPreset::kDefault || h.passed_selection || !options.box_selection;
    (selected ? result.hypotheses : result.rejected).push_back(std::move(h));
  }
  if (options.max_hypotheses > 0 && result.hypotheses.size() > static_cast<size_t>(options.max_hypotheses)) {
    result.hypotheses.resize(static_cast<size_t>(options.max_hypotheses));
  }
}

void recognizePlanned(const Model& model, const Plan& plan, const Features& features, const Scene* scene,
                      const RecognitionOptions& options, RecognitionResult& result) {
  result.keypoints = features.size();
  throwIfStopped(options.should_stop, "codeword activation");
  const auto activations = activateCodewords(model, plan, features, options, result.timings);
  result.gravity = features.gravity;
  std::vector<Hypothesis> all = findAllPeaks(model, plan, features, activations, options, result);
  const bool shapes = std::any_of(plan.categories.begin(), plan.categories.end(),
                                  [&](int c) { return hasShapes(model.categories[static_cast<size_t>(c)]); });
  if (options.preset == RecognitionPreset::kDefault && options.verify && scene != nullptr && shapes) {
    verifyPeaks(model, plan, features, *scene, options, all, result);
  }
  selectHypotheses(std::move(all), features, options, result);
  if (options.keep_votes) result.keypoint_positions = features.positions;
}

// The plan with each category's calibration for the kind of scene the features come from.
Plan forScene(Plan plan, const Features& features) {
  if (features.organized) return plan;
  for (auto& curve : plan.confidence) {
    if (curve.cloud_calibration) curve.calibration = curve.cloud_calibration;
  }
  return plan;
}

}  // namespace

RecognitionResult recognizeFeatures(const Model& model, const Features& features, const RecognitionOptions& options,
                                    const Scene* scene) {
  const Plan plan = planRecognition(model, options);
  RecognitionResult result;
  recognizePlanned(model, forScene(plan, features), features, scene, options, result);
  return result;
}

RecognitionResult recognize(const Model& model, const Scene& scene, const RecognitionOptions& options) {
  if (!scene.cloud || scene.cloud->empty()) {
    throw Error(ErrorCode::kInvalidInput, "scene " + scene.source + " has no points");
  }
  const Plan plan = planRecognition(model, options);
  RecognitionResult result;
  const Scene seen = lookedAt(scene);  // a map seen from nowhere from its middle
  result.viewpoint = seen.sensor_origin;
  const FrontEndResult front = extractFeatures(seen, model.front_end, model.front_end.smoothing.enabled,
                                               &result.timings, options.should_stop);
  result.input_points = front.input_points;
  result.surface_points = front.surface_points;
  recognizePlanned(model, forScene(plan, front.features), front.features, &seen, options, result);
  return result;
}

}  // namespace ism
