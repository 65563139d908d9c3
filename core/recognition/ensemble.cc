#include "core/recognition/ensemble.h"

#include <algorithm>
#include <string>

#include "core/common/error.h"
#include "core/common/upright_box.h"
#include "core/gravity/viewpoint.h"
#include "core/model/model_file.h"
#include "core/recognition/suppression.h"

namespace ism {
namespace {

void checkMembers(const std::vector<const Model*>& models, const RecognitionOptions& options) {
  if (models.empty()) throw Error(ErrorCode::kInvalidInput, "an ensemble needs at least one model");
  if (options.preset == RecognitionPreset::kSeed) {
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
    bool same = other.categories.size() == first.categories.size();
    for (size_t c = 0; same && c < first.categories.size(); ++c) same = other.categories[c].name == first.categories[c].name;
    if (!same) {
      throw Error(ErrorCode::kInvalidInput,
                  "model " + std::to_string(m + 1) + " of the ensemble has other categories than the first");
    }
  }
}

// Adds `from`'s stages to `into`, stage by stage by name: the ensemble's time in each.
void addTimings(const StageTimings& from, StageTimings& into) {
  for (const auto& stage : from.stages) {
    auto at = std::find_if(into.stages.begin(), into.stages.end(), [&](const auto& s) { return s.first == stage.first; });
    if (at == into.stages.end()) {
      into.add(stage.first, stage.second);
    } else {
      at->second += stage.second;
    }
  }
}

}  // namespace

RecognitionResult recognizeEnsembleFeatures(const std::vector<const Model*>& models, const Features& features,
                                            const RecognitionOptions& options, const Scene* scene,
                                            const EnsembleParams& params) {
  checkMembers(models, options);
  if (models.size() == 1) return recognizeFeatures(*models.front(), features, options, scene);
  RecognitionOptions each = options;
  each.min_confidence = 0;  // down to the lowest a model looks at: the others may vouch for it
  each.max_hypotheses = 0;
  RecognitionResult result;
  struct Fused {
    Hypothesis best;  // the most confident model's answer here
    UprightBox box;   // its box in the gravity frame
    std::vector<bool> from;  // which models answered here
    float sum = 0;           // their confidences
  };
  const Eigen::Matrix3f to_gravity = features.gravity ? features.gravity->toGravity() : Eigen::Matrix3f::Identity();
  std::vector<std::pair<Hypothesis, size_t>> answers;
  for (size_t m = 0; m < models.size(); ++m) {
    RecognitionResult own = recognizeFeatures(*models[m], features, each, scene);
    addTimings(own.timings, result.timings);
    if (m == 0) {
      result.gravity = own.gravity;
      result.keypoints = own.keypoints;
      result.keypoint_positions = std::move(own.keypoint_positions);
      result.votes = std::move(own.votes);
    }
    for (auto& h : own.hypotheses) answers.emplace_back(std::move(h), m);
    for (auto& h : own.rejected) result.rejected.push_back(std::move(h));
  }
  std::stable_sort(answers.begin(), answers.end(),
                   [](const auto& a, const auto& b) { return a.first.confidence > b.first.confidence; });
  std::vector<Fused> fused;
  for (auto& [h, m] : answers) {
    const UprightBox box = uprightBoxOf(h.box, to_gravity);
    Fused* into = nullptr;
    float best_iou = params.min_iou;
    for (auto& f : fused) {
      if (f.from[m] || f.best.category != h.category) continue;
      const float iou = intersectionOverUnion(box, f.box);
      if (iou >= best_iou) {
        best_iou = iou;
        into = &f;
      }
    }
    const float confidence = h.confidence;
    if (into == nullptr) {  // the most confident answer here, as the answers come sorted
      into = &fused.emplace_back();
      into->from.assign(models.size(), false);
      into->box = box;
      into->best = std::move(h);
    }
    into->from[m] = true;
    into->sum += confidence;
  }
  std::vector<Hypothesis> all;
  all.reserve(fused.size());
  for (auto& f : fused) {
    f.best.confidence = f.sum / static_cast<float>(models.size());
    // Another category's confidence as one model saw it says little beside the mean: the
    // alternatives are the fused answers of other categories this one wins over (below).
    f.best.alternatives.clear();
    all.push_back(std::move(f.best));
  }
  if (options.one_answer_per_object) {
    all = suppressOverlaps(std::move(all), to_gravity, options.suppression);
  } else {
    std::stable_sort(all.begin(), all.end(), [](const Hypothesis& a, const Hypothesis& b) { return a.confidence > b.confidence; });
  }
  for (auto& h : all) {
    if (h.confidence >= options.min_confidence) result.hypotheses.push_back(std::move(h));
  }
  if (options.max_hypotheses > 0 && result.hypotheses.size() > static_cast<size_t>(options.max_hypotheses)) {
    result.hypotheses.resize(static_cast<size_t>(options.max_hypotheses));
  }
  return result;
}

RecognitionResult recognizeEnsemble(const std::vector<const Model*>& models, const Scene& scene,
                                    const RecognitionOptions& options, const EnsembleParams& params) {
  checkMembers(models, options);
  if (models.size() == 1) return recognize(*models.front(), scene, options);
  if (!scene.cloud || scene.cloud->empty()) {
    throw Error(ErrorCode::kInvalidInput, "scene " + scene.source + " has no points");
  }
  const Scene seen = lookedAt(scene);  // a map seen from nowhere from its middle
  StageTimings front_timings;
  const Model& first = *models.front();
  const FrontEndResult front =
      extractFeatures(seen, first.front_end, first.front_end.smoothing.enabled, &front_timings, options.should_stop);
  RecognitionResult result = recognizeEnsembleFeatures(models, front.features, options, &seen, params);
  addTimings(result.timings, front_timings);
  result.timings = std::move(front_timings);
  result.viewpoint = seen.sensor_origin;
  result.input_points = front.input_points;
  result.surface_points = front.surface_points;
  return result;
}

}  // namespace ism
