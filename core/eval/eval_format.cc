// Text tables and JSON documents of evaluation results.
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/eval/eval.h"

namespace ism {
namespace {

using nlohmann::json;

// First row is the header; the first column is left-aligned, the others right-aligned.
std::string alignedTable(const std::vector<std::vector<std::string>>& rows) {
  std::vector<size_t> widths;
  for (const auto& row : rows) {
    widths.resize(std::max(widths.size(), row.size()), 0);
    for (size_t c = 0; c < row.size(); ++c) widths[c] = std::max(widths[c], row[c].size());
  }
  std::ostringstream out;
  for (const auto& row : rows) {
    std::string line;
    for (size_t c = 0; c < row.size(); ++c) {
      const std::string pad(widths[c] - row[c].size(), ' ');
      line += c == 0 ? row[c] + pad : "  " + pad + row[c];
    }
    out << line << "\n";
  }
  return out.str();
}

std::string fixed(double value, int digits) {
  if (std::isnan(value)) return "-";
  std::ostringstream out;
  out.setf(std::ios::fixed);
  out.precision(digits);
  out << value;
  return out.str();
}

std::string percent(double fraction) { return std::isnan(fraction) ? "-" : fixed(100.0 * fraction, 1) + "%"; }

std::string countTable(const CountTable& table, const std::string& corner) {
  std::vector<std::vector<std::string>> rows{{corner}};
  rows[0].insert(rows[0].end(), table.cols.begin(), table.cols.end());
  for (size_t r = 0; r < table.rows.size(); ++r) {
    rows.push_back({table.rows[r]});
    for (int n : table.counts[r]) rows.back().push_back(std::to_string(n));
  }
  return alignedTable(rows);
}

json countJson(const CountTable& table) {
  return {{"rows", table.rows}, {"cols", table.cols}, {"counts", table.counts}};
}

}  // namespace

double meanAp25(const RealCombination& combination) {
  double sum = 0;
  int n = 0;
  for (const auto& k : combination.classes) {
    if (k.objects == 0) continue;
    sum += k.ap25;
    ++n;
  }
  return n == 0 ? NAN : sum / n;
}

std::string formatBaseline(const BaselineResult& result) {
  std::ostringstream out;
  out << "Baseline on synthetic scans: " << result.categories.size() << " categories, " << result.training_scans
      << " training scans, " << result.test_scans << " test scans; test scans rendered + described in "
      << fixed(result.scan_seconds, 1) << " s, training (its scans included) " << fixed(result.train_seconds, 1) << " s\n";
  for (const auto& c : result.combinations) {
    out << "\n== " << c.strategy << ": accuracy " << percent(c.accuracy) << ", recognition "
        << fixed(c.recognition_ms, 0) << " ms\n"
        << "hypothesis generated (scans whose model category has a hypothesis above threshold):\n"
        << countTable(c.generated, "test \\ model")
        << "confusion after box selection (best selected hypothesis):\n"
        << countTable(c.confusion, "test \\ result");
  }
  return out.str();
}

std::string formatReal(const RealResult& result) {
  std::ostringstream out;
  std::vector<std::vector<std::string>> scenes{
      {"scene", "points", "surface", "keypoints", "viewpoint", "load ms", "front end ms", "recognition ms"}};
  for (const auto& s : result.scenes) {
    double recognition = 0;
    for (double ms : s.recognition_ms) recognition += ms;
    scenes.push_back({s.name, std::to_string(s.points), std::to_string(s.surface_points), std::to_string(s.keypoints),
                      fixed(s.viewpoint.x(), 2) + "," + fixed(s.viewpoint.y(), 2) + "," + fixed(s.viewpoint.z(), 2),
                      fixed(s.load_ms, 0), fixed(s.front_end_ms, 0), fixed(recognition, 0)});
  }
  out << alignedTable(scenes);
  for (const auto& c : result.combinations) {
    std::vector<std::vector<std::string>> rows{
        {"class", "model categories", "objects", "TP", "FP", "FN", "r", "AP", "FP/scan", "AP@0.25", "TP@0.25"}};
    for (const auto& k : c.classes) {
      std::string models;
      for (const auto& m : k.model_categories) models += (models.empty() ? "" : ",") + m;
      rows.push_back({k.name, models, std::to_string(k.objects), std::to_string(k.tp), std::to_string(k.fp),
                      std::to_string(k.fn), percent(k.rate), percent(k.ap),
                      fixed(k.scenes > 0 ? static_cast<double>(k.fp) / k.scenes : NAN, 1), percent(k.ap25),
                      std::to_string(k.tp25)});
    }
    out << "\n== " << c.strategy << "\n"
        << alignedTable(rows) << "mAP@0.25 " << percent(meanAp25(c)) << " over the classes with objects; r and FP: "
        << "the seed's centre rule; AP@0.25: 3D boxes in the gravity frame\n";
  }
  return out.str();
}

std::string baselineToJson(const BaselineResult& result) {
  json combinations = json::array();
  for (const auto& c : result.combinations) {
    combinations.push_back({{"strategy", c.strategy},
                            {"accuracy", c.accuracy},
                            {"recognition_ms", c.recognition_ms},
                            {"generated", countJson(c.generated)},
                            {"confusion", countJson(c.confusion)}});
  }
  json doc = {{"categories", result.categories},   {"training_scans", result.training_scans},
              {"test_scans", result.test_scans},   {"scan_seconds", result.scan_seconds},
              {"train_seconds", result.train_seconds}, {"combinations", combinations}};
  return doc.dump(2);
}

std::string realToJson(const RealResult& result) {
  json scenes = json::array();
  for (size_t i = 0; i < result.scenes.size(); ++i) {
    const SceneRun& s = result.scenes[i];
    json per_strategy = json::array();
    for (size_t c = 0; c < result.combinations.size(); ++c) {
      const auto& counts = result.combinations[c].scene_tp_fp_fn[i];
      per_strategy.push_back({{"strategy", result.combinations[c].strategy},
                              {"recognition_ms", s.recognition_ms[c]},
                              {"tp", counts[0]}, {"fp", counts[1]}, {"fn", counts[2]}});
    }
    scenes.push_back({{"scene", s.name},
                      {"points", s.points},
                      {"surface_points", s.surface_points},
                      {"keypoints", s.keypoints},
                      {"viewpoint", {s.viewpoint.x(), s.viewpoint.y(), s.viewpoint.z()}},
                      {"load_ms", s.load_ms},
                      {"front_end_ms", s.front_end_ms},
                      {"strategies", per_strategy}});
  }
  json combinations = json::array();
  for (const auto& c : result.combinations) {
    json classes = json::array();
    for (const auto& k : c.classes) {
      json pr = json::array();
      for (const auto& [recall, precision] : k.pr25) pr.push_back({recall, precision});
      json ranked = json::array();
      for (const auto& [confidence, is_tp] : k.ranked25) ranked.push_back({confidence, is_tp});
      json outcomes = json::array();
      for (const auto& o : k.outcomes) {
        outcomes.push_back({{"scene", o.scene}, {"best_iou", o.best_iou}, {"best_iou_confidence", o.best_iou_confidence},
                            {"nearest_distance", std::isinf(o.nearest_distance) ? json(nullptr) : json(o.nearest_distance)}});
      }
      json candidates = json::array();
      for (const auto& d : k.candidates) {
        candidates.push_back({{"scene", d.scene}, {"category", d.category}, {"tp25", d.tp25}, {"confidence", d.confidence},
                              {"score", d.score}, {"support", d.support},
                              {"fit", d.verified ? json(d.fit) : json(nullptr)},
                              {"profile_distance", d.verified ? json(d.profile_distance) : json(nullptr)}});
      }
      classes.push_back({{"class", k.name}, {"model_categories", k.model_categories}, {"objects", k.objects},
                         {"scenes", k.scenes}, {"tp", k.tp}, {"fp", k.fp}, {"fn", k.fn}, {"rate", k.rate},
                         {"ap", k.ap}, {"ap25", k.ap25}, {"tp25", k.tp25}, {"fp25", k.fp25},
                         {"recall_precision25", pr}, {"confidence_tp25", ranked},
                         {"objects_outcome", outcomes}, {"candidates", candidates}});
    }
    combinations.push_back({{"strategy", c.strategy}, {"classes", classes}, {"map25", meanAp25(c)}});
  }
  return json{{"scenes", scenes}, {"combinations", combinations}}.dump(2);
}

}  // namespace ism
