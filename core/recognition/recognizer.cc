#include "core/recognition/recognizer.h"

#include <algorithm>
#include <cmath>
#include <chrono>
#include <functional>
#include <iterator>
#include <map>

#include "core/common/error.h"
#include "core/common/upright_box.h"
#include "core/gravity/viewpoint.h"
#include "core/model/model_file.h"
#include "core/recognition/suppression.h"
#include "core/recognition/top_extent.h"
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
  float operator()(const Hypothesis& peak) const { return (*this)(peak.score, peak.support, peak.verification); }
  // A peak of `score` from `support` keypoints, with the fit `verification` found there.
  float operator()(float score, int support, const std::optional<Verification>& verification) const {
    if (calibration) {
      return verification ? calibration->confidence(score, support, verification->fit(), verification->profile_distance)
                          : calibration->confidence(score, support);
    }
    return threshold > 0 ? 1.0f - std::exp2(-score / threshold) : 1.0f;
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

// One model of the call and its plan.
struct Member {
  const Model* model = nullptr;
  Plan plan;
};

void checkEnsemble(const std::vector<const Model*>& models, const RecognitionOptions& options) {
  if (models.empty()) throw Error(ErrorCode::kInvalidInput, "an ensemble needs at least one model");
  if (models.size() > 1 && options.preset == RecognitionPreset::kSeed) {
    throw Error(ErrorCode::kInvalidInput, "an ensemble answers with the default preset, not the seed's");
  }
  const Model& first = *models.front();
  for (size_t m = 1; m < models.size(); ++m) {
    const Model& other = *models[m];
    if (!sameFrontEnd(first, other)) {
      throw Error(ErrorCode::kInvalidInput, "model " + std::to_string(m + 1) +
                                                " of the ensemble has another front end than the first: its models "
                                                "must describe a scene alike");
    }
    if (!first.sameCategories(other)) {
      throw Error(ErrorCode::kInvalidInput,
                  "model " + std::to_string(m + 1) + " of the ensemble has other categories than the first");
    }
  }
}

// The models and their draws (Model::draws), each with its plan. The seed's preset, and a
// separated codebook (which draws are trained without), answer with the models alone.
std::vector<Member> planMembers(const std::vector<const Model*>& models, const RecognitionOptions& options) {
  const bool draws = options.preset == RecognitionPreset::kDefault && options.strategy.codebook == CodebookType::kGlobal;
  std::vector<const Model*> all;
  for (const Model* model : models) {
    all.push_back(model);
    if (!draws) continue;
    for (const Model& draw : model->draws) all.push_back(&draw);
  }
  checkEnsemble(all, options);
  std::vector<Member> members;
  for (const Model* model : all) members.push_back({model, planRecognition(*model, options)});
  return members;
}

double msSince(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since).count();
}

// The codewords each category's votes come from: one activation serves every category with the
// global codebook; separated codebooks each need their own.
std::vector<std::vector<Activation>> activateCodewords(const Member& member, const Features& features,
                                                       const RecognitionOptions& options) {
  const Strategy& strategy = options.strategy;
  const bool global = strategy.codebook == CodebookType::kGlobal;
  std::vector<std::vector<Activation>> activations(member.plan.categories.size());
  for (size_t s = 0; s < member.plan.categories.size() && !(global && s > 0); ++s) {
    const CategoryModel& c = member.model->categories[static_cast<size_t>(member.plan.categories[s])];
    const Codebook& codebook = global ? *member.model->global_codebook : *c.own_codebook;
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

// The time each stage of the models' searches took, summed over the models.
struct SearchTimes {
  double activate_ms = 0, vote_ms = 0, peak_ms = 0;
};

// Every planned category's peaks of one model, one category's Hough space at a time: it is the
// bulk of the memory on a room scan. In the default preset each peak gets its confidence and
// upright box, peaks that cannot reach `lowest` confidence are dropped and peaks outside the
// category's height prior go to `rejected` (when given). With keep_votes the votes go to `votes`.
// The codewords activated go to `activations` (activateCodewords).
std::vector<Hypothesis> findAllPeaks(const Member& member, const Features& features, const RecognitionOptions& options,
                                     float lowest, std::vector<Hypothesis>* rejected, std::vector<Vote>* votes,
                                     std::vector<std::vector<Activation>>& activations, SearchTimes& times) {
  const Strategy& strategy = options.strategy;
  const Model& model = *member.model;
  const Plan& plan = member.plan;
  const bool global = strategy.codebook == CodebookType::kGlobal;
  auto start = std::chrono::steady_clock::now();
  activations = activateCodewords(member, features, options);
  times.activate_ms += msSince(start);
  std::vector<Hypothesis> all;
  for (size_t s = 0; s < plan.categories.size(); ++s) {
    const std::vector<Activation>& activated = activations[global ? 0 : s];
    start = std::chrono::steady_clock::now();
    const HoughSpace hough(model, plan.categories[s], features, activated, strategy, HoughSpace::kMaxGridBins,
                           HoughSpace::kMaxKeptVoteBins, options.should_stop);
    times.vote_ms += msSince(start);
    throwIfStopped(options.should_stop, "voting");
    start = std::chrono::steady_clock::now();
    const PeakCentre centre = options.preset == RecognitionPreset::kSeed ? PeakCentre::kBin : options.peak_centre;
    auto peaks = hough.findPeaks(plan.thresholds[s], centre, options.should_stop);
    const CategoryModel& category = model.categories[static_cast<size_t>(plan.categories[s])];
    for (auto& peak : peaks) {
      peak.confidence = plan.confidence[s](peak);
      if (options.preset == RecognitionPreset::kSeed) {
        all.push_back(std::move(peak));
        continue;
      }
      if (plan.confidence[s].best(peak) < lowest) continue;
      estimateUprightBox(hough.caster(), category.bin_size / 2, peak);
      peak.passed_selection = withinHeightPrior(peak, category, features, priorSlack(model, category));
      if (peak.passed_selection) {
        all.push_back(std::move(peak));
      } else if (rejected != nullptr) {
        rejected->push_back(std::move(peak));
      }
    }
    times.peak_ms += msSince(start);
    throwIfStopped(options.should_stop, "hypothesis search");
    if (votes != nullptr) {
      auto cast = castVotes(model, plan.categories[s], features, activated, strategy);
      std::move(cast.begin(), cast.end(), std::back_inserter(*votes));
    }
  }
  return all;
}

// The answers of a flat-topped category (top_extent.h), whose boxes span the table top the scene
// measured, take the supporting keypoints of the category's peaks (`peaks`, per model) that answer
// nothing of their own (answering[m][i] false) and whose centre their box holds: verified or not,
// so that whatever min_confidence leaves unverified, below it, or refused by the scene's checks
// lends the same support. A long top's keypoints vote for centres all along it, and one answer
// then stands for every peak the top gave, as for the peaks it merged
// (SuppressionParams::merge_support). The boxes of chairs and couches are their fitted shapes',
// which may hold a neighbour's weak peaks. Only without SuppressionParams::top_support, which
// collects a table's support at its box's centre instead (supportAtTops).
void absorbWeakSupport(std::vector<Hypothesis>::iterator first, std::vector<Hypothesis>::iterator last,
                       const std::vector<std::vector<Hypothesis>>& peaks,
                       const std::vector<std::vector<bool>>& answering, const Eigen::Matrix3f& to_gravity) {
  for (auto answer = first; answer != last; ++answer) {
    const UprightBox box = uprightBoxOf(answer->box, to_gravity);
    for (size_t m = 0; m < peaks.size(); ++m) {
      for (size_t i = 0; i < peaks[m].size(); ++i) {
        if (answering[m][i]) continue;
        const Eigen::Vector3f center = to_gravity * peaks[m][i].center;
        if (insideFootprint(center, box) && std::abs(center.z() - box.center.z()) <= box.size.z() / 2) {
          mergeSupport(*answer, peaks[m][i]);
        }
      }
    }
  }
}

// Default preset, per category: each model's peaks merged to one per object, and the models'
// peaks grouped by object (ensemble.h). In each group that can reach min_confidence, with `scene`,
// each model's peak is verified against it, until the models verified so far rule the group out,
// and its confidence made again with the fit; a peak whose agreeing surface is mostly another's of
// its model and category (their boxes overlap too little to be merged) answers nothing. In the
// groups whose verified mean reaches min_confidence, the scene's checks (scene_checks.h) send the
// peaks they contradict to result.rejected (the first model's) and mark the ones they refute, which are
// rejected after the answers per object are chosen (selectHypotheses). A group's answer is its
// most confident model's, at the mean of the models' confidences (0 for a model without an
// answer there).
std::vector<Hypothesis> answerPerCategory(const std::vector<Member>& members, const Features& features,
                                          const Scene* scene, const RecognitionOptions& options,
                                          std::vector<std::vector<Hypothesis>> peaks, RecognitionResult& result) {
  ScopedStage stage(&result.timings, "verify");
  const Model& model = *members.front().model;
  const Plan& plan = members.front().plan;
  const Eigen::Matrix3f to_gravity = features.gravity ? features.gravity->toGravity() : Eigen::Matrix3f::Identity();
  const float lowest = std::max(options.min_confidence, kLowestConfidence);
  const auto count = static_cast<float>(members.size());
  // In an ensemble, a model's answer counts towards the mean down to the lowest confidence.
  const float own_lowest = members.size() > 1 ? kLowestConfidence : lowest;
  std::optional<VerificationScene> view;
  if (scene != nullptr) view = makeVerificationScene(*scene, features.gravity, options.verification);
  SuppressionParams before_confidence = options.suppression;
  before_confidence.merge_support = false;  // the confidence reads each peak's own support
  std::vector<Hypothesis> answers;
  for (size_t s = 0; s < plan.categories.size(); ++s) {
    const CategoryModel& category = model.categories[static_cast<size_t>(plan.categories[s])];
    const bool absorb = view && options.suppression.merge_support && !options.suppression.top_support &&
                        options.scene_checks.top_extent.enabled &&
                        flatTopped(category, options.scene_checks.top_extent);
    std::vector<std::vector<Hypothesis>> own(members.size());
    for (size_t m = 0; m < members.size(); ++m) {
      for (auto& h : peaks[m]) {
        if (h.category == category.name) own[m].push_back(std::move(h));
      }
      if (options.one_answer_per_object) own[m] = suppressOverlaps(std::move(own[m]), to_gravity, before_confidence);
    }
    // Verification moves the peaks out of `own`; absorbWeakSupport reads them all, as they were.
    const std::vector<std::vector<Hypothesis>> all_peaks = absorb ? own : std::vector<std::vector<Hypothesis>>{};
    // Groups that cannot reach `lowest` whatever the fits are not looked at, most confident first.
    struct Group {
      float confidence = 0;
      PeakGroup peaks;
      std::vector<float> reach;  // per model, the most its peak here can reach (0 without one)
    };
    std::vector<Group> groups;
    for (auto& group : groupPeaks(own, to_gravity, options.ensemble)) {
      Group g{0, std::move(group), std::vector<float>(members.size(), 0.0f)};
      float best = 0;
      for (size_t m = 0; m < members.size(); ++m) {
        if (g.peaks.peak[m] < 0) continue;
        const Hypothesis& peak = own[m][static_cast<size_t>(g.peaks.peak[m])];
        g.reach[m] = members[m].plan.confidence[s].best(peak);
        best += g.reach[m];
        g.confidence += peak.confidence;
      }
      g.confidence /= count;
      if (best / count >= lowest) groups.push_back(std::move(g));
    }
    std::stable_sort(groups.begin(), groups.end(),
                     [](const Group& a, const Group& b) { return a.confidence > b.confidence; });
    // Model by model, each peak verified and its confidence made again with the fit; a duplicate
    // answers nothing. A group's mean counts the models verified so far at what they answered and
    // the others at the most they can reach, so that a later model leaves unverified the peaks of
    // groups the earlier ones have ruled out. The first model verifies every group that can reach
    // `lowest`, as one model alone does.
    std::vector<std::vector<std::optional<Hypothesis>>> answered(groups.size(),
                                                                 std::vector<std::optional<Hypothesis>>(members.size()));
    // `verified` sums as the answers' mean below does, so that the checks skip only groups it skips.
    std::vector<float> verified(groups.size(), 0.0f);
    std::vector<double> unverified(groups.size(), 0.0);
    for (size_t g = 0; g < groups.size(); ++g) {
      for (float r : groups[g].reach) unverified[g] += r;
    }
    std::vector<std::vector<size_t>> verified_groups(members.size());  // per model, most confident first
    for (size_t m = 0; m < members.size(); ++m) {
      const Model& own_model = *members[m].model;
      const auto peakIn = [&](size_t g) -> Hypothesis& {
        return own[m][static_cast<size_t>(groups[g].peaks.peak[m])];
      };
      // verifyHypotheses orders them most confident first (a stable sort): sorted so already, each
      // keeps its group. The slack keeps rounding from ruling out a group that reaches `lowest`.
      std::vector<size_t>& sorted_group = verified_groups[m];
      for (size_t g = 0; g < groups.size(); ++g) {
        const bool open = (verified[g] + unverified[g]) / count >= static_cast<double>(lowest) - 1e-6;
        unverified[g] -= groups[g].reach[m];
        if (groups[g].peaks.peak[m] < 0 || !open) continue;
        sorted_group.push_back(g);
      }
      std::stable_sort(sorted_group.begin(), sorted_group.end(),
                       [&](size_t a, size_t b) { return peakIn(a).confidence > peakIn(b).confidence; });
      std::vector<Hypothesis> sorted;
      for (size_t g : sorted_group) sorted.push_back(std::move(peakIn(g)));  // each peak is in one group
      if (view) {
        verifyHypotheses(*view, own_model, sorted, options.verification, options.should_stop);
        result.verified += sorted.size();
      }
      for (size_t i = 0; i < sorted.size(); ++i) {
        Hypothesis& h = sorted[i];
        if (options.one_answer_per_object && h.verification && h.verification->duplicate()) continue;
        if (view) {
          h.confidence = members[m].plan.confidence[s](h);
          if (h.confidence < own_lowest) continue;
        }
        verified[sorted_group[i]] += h.confidence;
        answered[sorted_group[i]][m] = std::move(h);
      }
    }
    // The scene's checks, which can only take answers away, in the groups whose verified mean
    // reaches `lowest`: the peaks they contradict are rejected (the first model's reported, in its
    // order), the ones they refute marked. What the checks need from the training shapes is worked
    // out only for a category with answers to check: most frames have none for most categories.
    if (view) {
      for (size_t m = 0; m < members.size(); ++m) {
        const Model& own_model = *members[m].model;
        const CategoryModel& own_category = own_model.categories[static_cast<size_t>(plan.categories[s])];
        std::optional<SceneChecks> checks;
        for (size_t g : verified_groups[m]) {
          std::optional<Hypothesis>& h = answered[g][m];
          if (!h || verified[g] / count < lowest) continue;
          if (!checks) checks.emplace(own_model, own_category, options.scene_checks);
          const SceneVerdict verdict = (*checks)(*view, *h, to_gravity);
          if (verdict == SceneVerdict::kRejected) {
            h->passed_selection = false;
            if (m == 0) result.rejected.push_back(std::move(*h));
            h.reset();
            continue;
          }
          h->refuted = verdict == SceneVerdict::kRefuted;
        }
      }
    }
    // A group's answer: its most confident model's, at the mean of the models' confidences.
    const size_t first_answer = answers.size();
    std::vector<std::vector<bool>> answering(members.size());  // per model and peak of all_peaks
    for (size_t m = 0; m < members.size(); ++m) answering[m].assign(absorb ? own[m].size() : 0, false);
    for (size_t g = 0; g < groups.size(); ++g) {
      float sum = 0;
      size_t best = members.size();
      for (size_t m = 0; m < members.size(); ++m) {
        const std::optional<Hypothesis>& a = answered[g][m];
        if (!a) continue;
        sum += a->confidence;
        if (best == members.size() || a->confidence > answered[g][best]->confidence) best = m;
      }
      if (best == members.size() || sum / count < lowest) continue;
      Hypothesis h = std::move(*answered[g][best]);
      h.confidence = sum / count;
      answers.push_back(std::move(h));
      if (absorb) answering[best][static_cast<size_t>(groups[g].peaks.peak[best])] = true;
    }
    if (absorb) {
      absorbWeakSupport(answers.begin() + static_cast<std::ptrdiff_t>(first_answer), answers.end(), all_peaks,
                        answering, to_gravity);
    }
  }
  return answers;
}

// The seed's preset ranks the hypotheses of every category against each other by
// Hypothesis::relativeScore and sorts them into result.hypotheses and result.rejected by their
// box test. The default preset keeps one answer per object and the confident ones, best first.
void selectHypotheses(std::vector<Hypothesis> all, const Features& features, const RecognitionOptions& options,
                      const std::function<FloorKind(const std::string&)>& floor_kind, RecognitionResult& result) {
  ScopedStage stage(&result.timings, "select");
  if (options.preset == RecognitionPreset::kSeed) {
    std::stable_sort(all.begin(), all.end(),
                     [](const Hypothesis& a, const Hypothesis& b) { return a.relativeScore() > b.relativeScore(); });
  } else {
    const Eigen::Matrix3f to_gravity = features.gravity ? features.gravity->toGravity() : Eigen::Matrix3f::Identity();
    // Before one answer per object: a dropped couch takes no chair's place.
    if (floor_kind) {
      dropSeatsUnderTops(all, floor_kind, to_gravity, options.scene_checks.seat_under_top, result.rejected);
    }
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

// SuppressionParams::top_support: each verified answer of a flat-topped category whose box spans
// the measured top is supported by the keypoints that voted into the bin at its box's centre, in
// any of the models (`activations[m]`, activateCodewords').
void supportAtTops(const std::vector<Member>& members, const std::vector<std::vector<std::vector<Activation>>>& activations,
                   const Features& features, const RecognitionOptions& options, std::vector<Hypothesis>& answers) {
  const bool global = options.strategy.codebook == CodebookType::kGlobal;
  const Plan& plan = members.front().plan;
  for (size_t s = 0; s < plan.categories.size(); ++s) {
    const CategoryModel& category = members.front().model->categories[static_cast<size_t>(plan.categories[s])];
    std::vector<Hypothesis*> tops;
    for (auto& h : answers) {
      if (h.category == category.name && h.verification && h.upright_box) tops.push_back(&h);
    }
    if (tops.empty() || !flatTopped(category, options.scene_checks.top_extent)) continue;
    std::vector<std::vector<int>> supporting(tops.size());  // ascending, each keypoint once
    for (size_t m = 0; m < members.size(); ++m) {
      const VoteCaster caster(*members[m].model, plan.categories[s], features, activations[m][global ? 0 : s],
                              options.strategy);
      for (size_t t = 0; t < tops.size(); ++t) {
        const std::vector<int> voting = keypointsVotingInto(caster, tops[t]->box.center, category.bin_size / 2);
        std::vector<int> both;
        std::set_union(supporting[t].begin(), supporting[t].end(), voting.begin(), voting.end(),
                       std::back_inserter(both));
        supporting[t] = std::move(both);
      }
    }
    for (size_t t = 0; t < tops.size(); ++t) {
      if (supporting[t].empty()) continue;  // nothing voted there: the peaks' support stays
      setSupport(*tops[t], std::move(supporting[t]), features);
      if (!options.return_keypoints) tops[t]->support_keypoints = {};
    }
  }
}

void recognizePlanned(const std::vector<Member>& members, const Features& features, const Scene* scene,
                      const RecognitionOptions& options, RecognitionResult& result) {
  result.keypoints = features.size();
  throwIfStopped(options.should_stop, "codeword activation");
  result.gravity = features.gravity;
  // An ensemble's models each look down to the lowest confidence: the others may vouch for a peak.
  const float lowest = members.size() > 1 ? kLowestConfidence : std::max(options.min_confidence, kLowestConfidence);
  SearchTimes times;
  std::vector<std::vector<Hypothesis>> peaks;
  std::vector<std::vector<std::vector<Activation>>> activations(members.size());
  for (size_t m = 0; m < members.size(); ++m) {  // the first model's rejected peaks and votes are reported
    peaks.push_back(findAllPeaks(members[m], features, options, lowest, m == 0 ? &result.rejected : nullptr,
                                 m == 0 && options.keep_votes ? &result.votes : nullptr, activations[m], times));
  }
  result.timings.add("activate", times.activate_ms);
  result.timings.add("vote", times.vote_ms);
  result.timings.add("hypotheses", times.peak_ms);
  const Model& first = *members.front().model;
  const bool shapes = std::any_of(members.front().plan.categories.begin(), members.front().plan.categories.end(),
                                  [&](int c) { return hasShapes(first.categories[static_cast<size_t>(c)]); });
  const bool verifying = options.verify && scene != nullptr && shapes;
  std::vector<Hypothesis> all;
  if (options.preset == RecognitionPreset::kDefault && (verifying || members.size() > 1)) {
    all = answerPerCategory(members, features, verifying ? scene : nullptr, options, std::move(peaks), result);
  } else {
    all = std::move(peaks.front());
  }
  // What each category is to the check of a seat under a table's top, worked out once per call
  // for the categories with answers.
  std::map<std::string, FloorKind> kinds;
  std::function<FloorKind(const std::string&)> floor_kind;
  if (verifying && options.preset == RecognitionPreset::kDefault && options.scene_checks.top_extent.enabled) {
    floor_kind = [&](const std::string& name) {
      auto known = kinds.find(name);
      if (known != kinds.end()) return known->second;
      const CategoryModel* category = first.find(name);
      const FloorKind kind = category ? floorKind(*category, options.scene_checks.top_extent,
                                                  options.scene_checks.seat_run, options.scene_checks.seat_under_top)
                                      : FloorKind::kOther;
      kinds.emplace(name, kind);
      return kind;
    };
  }
  selectHypotheses(std::move(all), features, options, floor_kind, result);
  if (verifying && options.preset == RecognitionPreset::kDefault && options.suppression.top_support &&
      options.scene_checks.top_extent.enabled) {
    ScopedStage stage(&result.timings, "support");
    supportAtTops(members, activations, features, options, result.hypotheses);
  }
  if (options.keep_votes) result.keypoint_positions = features.positions;
}

// The plan with each category's calibration for the kind of scene the features come from.
std::vector<Member> forScene(std::vector<Member> members, const Features& features) {
  if (features.organized) return members;
  for (auto& member : members) {
    for (auto& curve : member.plan.confidence) {
      if (curve.cloud_calibration) curve.calibration = curve.cloud_calibration;
    }
  }
  return members;
}

}  // namespace

RecognitionResult recognizeEnsembleFeatures(const std::vector<const Model*>& models, const Features& features,
                                            const RecognitionOptions& options, const Scene* scene) {
  const std::vector<Member> members = planMembers(models, options);
  RecognitionResult result;
  recognizePlanned(forScene(members, features), features, scene, options, result);
  return result;
}

RecognitionResult recognizeFeatures(const Model& model, const Features& features, const RecognitionOptions& options,
                                    const Scene* scene) {
  return recognizeEnsembleFeatures({&model}, features, options, scene);
}

RecognitionResult recognizeEnsemble(const std::vector<const Model*>& models, const Scene& scene,
                                    const RecognitionOptions& options) {
  if (!scene.cloud || scene.cloud->empty()) {
    throw Error(ErrorCode::kInvalidInput, "scene " + scene.source + " has no points");
  }
  const std::vector<Member> members = planMembers(models, options);
  const Model& first = *models.front();
  RecognitionResult result;
  const Scene seen = lookedAt(scene);  // a map seen from nowhere from its middle
  result.viewpoint = seen.sensor_origin;
  const FrontEndResult front = extractFeatures(seen, first.front_end, first.front_end.smoothing.enabled,
                                               &result.timings, options.should_stop);
  result.input_points = front.input_points;
  result.surface_points = front.surface_points;
  recognizePlanned(forScene(members, front.features), front.features, &seen, options, result);
  return result;
}

RecognitionResult recognize(const Model& model, const Scene& scene, const RecognitionOptions& options) {
  return recognizeEnsemble({&model}, scene, options);
}

}  // namespace ism
