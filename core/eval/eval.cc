#include "core/eval/eval.h"

#include <algorithm>
#include <chrono>
#include <iterator>

#include "core/common/error.h"
#include "core/recognition/recognizer.h"

namespace ism {
namespace {

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

int indexOf(const std::vector<std::string>& names, const std::string& name) {
  auto it = std::find(names.begin(), names.end(), name);
  return it == names.end() ? -1 : static_cast<int>(it - names.begin());
}

CountTable zeroTable(std::vector<std::string> rows, std::vector<std::string> cols) {
  CountTable table{std::move(rows), std::move(cols), {}};
  table.counts.assign(table.rows.size(), std::vector<int>(table.cols.size(), 0));
  return table;
}

}  // namespace

std::string strategyName(const Strategy& strategy) {
  std::string activation = strategy.activation.strategy == ActivationStrategy::kKnn
                               ? std::to_string(strategy.activation.k) + "nn"
                               : std::string("cutoff");
  const char* weighting = strategy.weighting == VoteWeighting::kCategorization ? "cw"
                          : strategy.weighting == VoteWeighting::kLocalization ? "lw"
                                                                               : "aw";
  const char* codebook = strategy.codebook == CodebookType::kGlobal ? "global" : "separated";
  return std::string(codebook) + " " + activation + "+" + weighting;
}

std::vector<NamedStrategy> seedCombinations(const Model& model) {
  std::vector<NamedStrategy> out;
  for (CodebookType codebook : {CodebookType::kGlobal, CodebookType::kSeparated}) {
    if (!model.has(codebook)) continue;
    for (auto [activation, weighting] : {std::pair{model.trained_knn, VoteWeighting::kLocalization},
                                         std::pair{model.trained_cutoff, VoteWeighting::kLocalization},
                                         std::pair{model.trained_knn, VoteWeighting::kActivation}}) {
      Strategy strategy{codebook, activation, weighting};
      out.push_back({strategyName(strategy), strategy});
    }
  }
  return out;
}

std::vector<Hypothesis> hypothesesForFeatures(const Model& model, const Features& features, const Strategy& strategy,
                                              const EvalRecognition& recognition, const Scene* scene,
                                              const std::vector<const Model*>& more) {
  RecognitionOptions options;
  options.strategy = strategy;
  options.preset = recognition.preset;
  options.box_selection = false;  // the tables count peaks before selection too
  options.min_confidence = 0;     // down to the lowest confidence recognition looks at
  options.verify = recognition.verify;
  options.suppression.shared_surface = recognition.shared_surface;
  options.suppression.merge_support = recognition.merge_support;
  options.suppression.top_support = recognition.top_support;
  options.peak_centre = recognition.peak_centre;
  options.verification.maps_in_3d = recognition.maps_in_3d;
  options.verification.icp_iterations = recognition.icp_iterations;
  options.verification.fit_terms = recognition.fit_terms;
  options.scene_checks = recognition.scene_checks;
  std::vector<const Model*> models = {&model};
  models.insert(models.end(), more.begin(), more.end());
  return recognizeEnsembleFeatures(models, features, options, scene).hypotheses;
}

MeshSplit splitMeshes(const std::vector<TrainingMesh>& meshes, int train_per_category, int test_per_category) {
  if (train_per_category < 1 || test_per_category < 1) {
    throw Error(ErrorCode::kInvalidInput, "need at least 1 training and 1 test mesh per category, got " +
                                              std::to_string(train_per_category) + " and " +
                                              std::to_string(test_per_category));
  }
  std::vector<std::string> categories;
  for (const auto& m : meshes) {
    if (indexOf(categories, m.category) < 0) categories.push_back(m.category);
  }
  MeshSplit split;
  for (const auto& category : categories) {
    std::vector<TrainingMesh> own;
    std::copy_if(meshes.begin(), meshes.end(), std::back_inserter(own),
                 [&](const TrainingMesh& m) { return m.category == category; });
    std::stable_sort(own.begin(), own.end(), [](const auto& a, const auto& b) { return a.path < b.path; });
    const size_t needed = static_cast<size_t>(train_per_category + test_per_category);
    if (own.size() < needed) {
      throw Error(ErrorCode::kInvalidInput, "category '" + category + "' has " + std::to_string(own.size()) +
                                                " meshes, the split needs " + std::to_string(needed));
    }
    split.train.insert(split.train.end(), own.begin(), own.begin() + train_per_category);
    split.test.insert(split.test.end(), own.begin() + train_per_category, own.begin() + needed);
  }
  return split;
}

int CountTable::at(const std::string& row, const std::string& col) const {
  int r = indexOf(rows, row), c = indexOf(cols, col);
  if (r < 0 || c < 0) throw Error(ErrorCode::kNotFound, "no cell (" + row + ", " + col + ") in the table");
  return counts[r][c];
}

BaselineResult evaluateBaseline(const Model& model, const std::vector<TrainingScan>& test_scans,
                                const std::vector<NamedStrategy>& strategies, const EvalRecognition& recognition,
                                const std::vector<Scene>& scenes) {
  if (!scenes.empty() && scenes.size() != test_scans.size()) {
    throw Error(ErrorCode::kInternal, "evaluateBaseline: " + std::to_string(scenes.size()) + " scenes for " +
                                          std::to_string(test_scans.size()) + " test scans");
  }
  BaselineResult result;
  for (const auto& c : model.categories) result.categories.push_back(c.name);
  result.test_scans = static_cast<int>(test_scans.size());
  std::vector<std::string> with_none = result.categories;
  with_none.push_back("none");
  for (const auto& s : strategies) {
    result.combinations.push_back(
        {s.name, zeroTable(result.categories, result.categories), zeroTable(result.categories, with_none), 0, 0});
  }
  for (size_t i = 0; i < test_scans.size(); ++i) {
    const TrainingScan& scan = test_scans[i];
    const Scene* scene = scenes.empty() ? nullptr : &scenes[i];
    const int row = indexOf(result.categories, scan.category);
    if (row < 0) {
      throw Error(ErrorCode::kInvalidInput, "test scan of category '" + scan.category + "' (mesh " +
                                                std::to_string(scan.model_index) + ") is not in the model");
    }
    for (size_t s = 0; s < strategies.size(); ++s) {
      BaselineCombination& combination = result.combinations[s];
      auto start = std::chrono::steady_clock::now();
      auto hypotheses = hypothesesForFeatures(model, scan.features, strategies[s].strategy, recognition, scene);
      combination.recognition_ms += 1000.0 * secondsSince(start);
      std::vector<bool> generated(result.categories.size(), false);
      int best = static_cast<int>(result.categories.size());  // "none"
      const bool seed = recognition.preset == RecognitionPreset::kSeed;
      for (const Hypothesis& h : hypotheses) {  // best first
        if (!seed && h.confidence < recognition.min_confidence) continue;
        generated[static_cast<size_t>(indexOf(result.categories, h.category))] = true;
        for (const auto& a : h.alternatives) {
          if (a.confidence >= recognition.min_confidence) generated[static_cast<size_t>(indexOf(result.categories, a.category))] = true;
        }
        if (h.passed_selection && best == static_cast<int>(result.categories.size())) best = indexOf(result.categories, h.category);
      }
      for (size_t col = 0; col < generated.size(); ++col) combination.generated.counts[row][col] += generated[col];
      ++combination.confusion.counts[row][best];
    }
  }
  for (auto& combination : result.combinations) {
    int correct = 0;
    for (size_t r = 0; r < result.categories.size(); ++r) correct += combination.confusion.counts[r][r];
    combination.accuracy = test_scans.empty() ? 0.0 : static_cast<double>(correct) / test_scans.size();
  }
  return result;
}

BaselineResult runBaseline(const MeshSplit& split, const TrainingParams& params, const EvalRecognition& recognition) {
  auto start = std::chrono::steady_clock::now();
  const Model model = train(split.train, params);
  const double train_seconds = secondsSince(start);

  start = std::chrono::steady_clock::now();
  // The seed preset verifies nothing, so only the default keeps the rendered scenes.
  std::vector<Scene> scenes;
  const bool keep_scenes = recognition.preset == RecognitionPreset::kDefault && recognition.verify;
  std::vector<TrainingScan> test_scans =
      scanMeshes(split.test, placeMeshes(split.test, params), params, keep_scenes ? &scenes : nullptr);
  const double scan_seconds = secondsSince(start);

  BaselineResult result = evaluateBaseline(model, test_scans, seedCombinations(model), recognition, scenes);
  result.training_scans = model.provenance.scans;
  result.scan_seconds = scan_seconds;
  result.train_seconds = train_seconds;
  return result;
}

}  // namespace ism
