// Real scenes with hand-marked ground truth: annotation parsing, the seed's matching rule,
// recognition rate and average precision.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/common/error.h"
#include "core/eval/eval.h"
#include "core/gravity/viewpoint.h"
#include "core/io/cloud_io.h"

namespace ism {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string lowercase(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

Eigen::Vector3f readVector3(const json& object, const char* field, const std::string& where) {
  auto it = object.find(field);
  if (it == object.end() || !it->is_array() || it->size() != 3 ||
      !std::all_of(it->begin(), it->end(), [](const json& v) { return v.is_number(); })) {
    throw Error(ErrorCode::kInvalidInput, where + ": \"" + field + "\" must be an array of 3 numbers");
  }
  return {(*it)[0].get<float>(), (*it)[1].get<float>(), (*it)[2].get<float>()};
}

bool contains(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

double millisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

double ratio(int num, int den) {
  return den == 0 ? std::numeric_limits<double>::quiet_NaN() : static_cast<double>(num) / den;
}

}  // namespace

AnnotatedScene readSceneAnnotation(const std::string& json_path) {
  std::ifstream in(json_path);
  if (!in) throw Error(ErrorCode::kNotFound, "ground truth " + json_path + " cannot be opened");
  json doc;
  try {
    doc = json::parse(in);
  } catch (const json::exception& e) {
    throw Error(ErrorCode::kInvalidInput, "ground truth " + json_path + " is not valid JSON: " + e.what());
  }
  if (!doc.is_object()) throw Error(ErrorCode::kInvalidInput, "ground truth " + json_path + " is not a JSON object");
  AnnotatedScene scene;
  scene.json_path = json_path;
  const fs::path path(json_path);
  scene.name = doc.value("scene", path.stem().string());
  scene.frame = doc.value("frame", "");
  const std::string cloud = doc.value("cloud", path.stem().string() + ".pcd");
  scene.cloud_path = (path.parent_path() / cloud).string();
  auto objects = doc.find("objects");
  if (objects == doc.end() || !objects->is_array()) {
    throw Error(ErrorCode::kInvalidInput, "ground truth " + json_path + " has no \"objects\" array");
  }
  // A camera frame levelled by hand gives its floor-aligned axes; the boxes are along them.
  if (doc.contains("floor_normal")) {
    const Eigen::Vector3f up = readVector3(doc, "floor_normal", json_path).normalized();
    Eigen::Vector3f a = doc.contains("axes_a") ? readVector3(doc, "axes_a", json_path) : Eigen::Vector3f::UnitX();
    a = (a - up * up.dot(a)).normalized();
    if (!up.allFinite() || !a.allFinite()) {
      throw Error(ErrorCode::kInvalidInput, json_path + ": \"floor_normal\" and \"axes_a\" do not span a frame");
    }
    scene.to_gravity.row(0) = a.transpose();
    scene.to_gravity.row(1) = up.cross(a).transpose();
    scene.to_gravity.row(2) = up.transpose();
  }
  scene.up_is_given = !doc.contains("floor_normal") && lowercase(scene.frame).find("z up") != std::string::npos;
  for (size_t i = 0; i < objects->size(); ++i) {
    const json& o = (*objects)[i];
    const std::string where = json_path + ": objects[" + std::to_string(i) + "]";
    if (!o.is_object() || !o.contains("category") || !o["category"].is_string()) {
      throw Error(ErrorCode::kInvalidInput, where + " has no \"category\" string");
    }
    GroundTruthObject object;
    object.category = o["category"].get<std::string>();
    object.center = readVector3(o, "center", where);
    object.size = o.contains("size") ? readVector3(o, "size", where) : Eigen::Vector3f::Zero();
    object.yaw = o.value("yaw", 0.0f);
    scene.objects.push_back(object);
  }
  if (!fs::exists(scene.cloud_path)) {
    throw Error(ErrorCode::kNotFound, "cloud " + scene.cloud_path + " of ground truth " + json_path + " does not exist");
  }
  return scene;
}

std::vector<std::string> findSceneAnnotations(const std::vector<std::string>& inputs) {
  std::vector<std::string> out;
  for (const auto& input : inputs) {
    const fs::path path(input);
    if (fs::is_directory(path)) {
      std::vector<std::string> found;
      for (const auto& entry : fs::directory_iterator(path)) {
        if (entry.is_regular_file() && lowercase(entry.path().extension().string()) == ".json") {
          found.push_back(entry.path().string());
        }
      }
      if (found.empty()) throw Error(ErrorCode::kNotFound, "folder " + input + " holds no scene .json files");
      std::sort(found.begin(), found.end());
      out.insert(out.end(), found.begin(), found.end());
      continue;
    }
    fs::path json_path = path;
    if (lowercase(path.extension().string()) != ".json") json_path.replace_extension(".json");
    if (!fs::exists(json_path)) {
      throw Error(ErrorCode::kNotFound, "no ground truth for " + input + ": " + json_path.string() + " does not exist");
    }
    out.push_back(json_path.string());
  }
  return out;
}

CategoryMapping defaultCategoryMapping() {
  return {{"office_chair", {"chair"}}, {"dining_chair", {"chair"}}, {"dining_table", {"table", "desk"}},
          {"couch", {"sofa"}}};
}

void addCategoryMapping(CategoryMapping& mapping, const std::string& spec) {
  const auto eq = spec.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == spec.size()) {
    throw Error(ErrorCode::kInvalidInput, "category mapping '" + spec + "' is not of the form model=gt1|gt2");
  }
  std::vector<std::string> targets;
  std::stringstream rest(spec.substr(eq + 1));
  for (std::string target; std::getline(rest, target, '|');) {
    if (target.empty()) throw Error(ErrorCode::kInvalidInput, "category mapping '" + spec + "' has an empty target");
    targets.push_back(target);
  }
  mapping[spec.substr(0, eq)] = targets;
}

ViewpointPolicy parseViewpointPolicy(const std::string& s) {
  if (s == "auto") return ViewpointPolicy::kAuto;
  if (s == "origin") return ViewpointPolicy::kOrigin;
  if (s == "room-centre") return ViewpointPolicy::kRoomCentre;
  throw Error(ErrorCode::kInvalidInput, "viewpoint policy '" + s + "' is not one of auto, origin, room-centre");
}

Eigen::Vector3f sceneViewpoint(const AnnotatedScene& annotation, const Scene& scene, ViewpointPolicy policy,
                               float eye_height) {
  // What recognition itself does (viewpoint.h): the file's pose, else the origin of a single
  // view, else the middle of a map.
  if (policy == ViewpointPolicy::kAuto) {
    ViewpointParams params;
    params.eye_height = eye_height;
    const auto view = mapViewpoint(scene, params);
    return view ? view->origin : scene.sensor_origin;
  }
  if (policy == ViewpointPolicy::kOrigin || scene.cloud->empty()) return Eigen::Vector3f::Zero();
  return roomCentreViewpoint(*scene.cloud, annotation.to_gravity.row(2).transpose(), eye_height);
}

std::vector<MatchLabel> matchDetections(const std::vector<ScoredDetection>& detections,
                                        const std::vector<Eigen::Vector3f>& objects) {
  std::vector<size_t> order(detections.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return detections[a].score > detections[b].score; });
  std::vector<MatchLabel> labels(detections.size(), MatchLabel::kFalsePositive);
  std::vector<bool> matched(objects.size(), false);
  std::vector<size_t> counted_fps;
  for (size_t i : order) {
    const ScoredDetection& d = detections[i];
    int nearest = -1;
    float nearest_distance = d.radius;
    for (size_t o = 0; o < objects.size(); ++o) {
      const float distance = (objects[o] - d.position).norm();
      if (!matched[o] && distance <= nearest_distance) {
        nearest = static_cast<int>(o);
        nearest_distance = distance;
      }
    }
    if (nearest >= 0) {
      matched[nearest] = true;
      labels[i] = MatchLabel::kTruePositive;
    } else if (std::any_of(counted_fps.begin(), counted_fps.end(), [&](size_t f) {
                 return (detections[f].position - d.position).norm() <= d.radius;
               })) {
      labels[i] = MatchLabel::kMergedFalsePositive;
    } else {
      counted_fps.push_back(i);
    }
  }
  return labels;
}

std::vector<bool> matchDetectionsByIou(const std::vector<ScoredDetection>& detections,
                                       const std::vector<UprightBox>& objects, float min_iou) {
  std::vector<size_t> order(detections.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return detections[a].score > detections[b].score; });
  std::vector<bool> is_tp(detections.size(), false);
  std::vector<bool> matched(objects.size(), false);
  for (size_t i : order) {
    int best = -1;
    float best_iou = 0;
    for (size_t o = 0; o < objects.size(); ++o) {
      const float iou = intersectionOverUnion(detections[i].box, objects[o]);
      if (iou > best_iou) {
        best = static_cast<int>(o);
        best_iou = iou;
      }
    }
    // As VOC and VoteNet do: a detection whose best object is taken already is a duplicate (FP),
    // it does not fall back to a worse overlap.
    if (best >= 0 && best_iou >= min_iou && !matched[static_cast<size_t>(best)]) {
      matched[static_cast<size_t>(best)] = true;
      is_tp[i] = true;
    }
  }
  return is_tp;
}

double averagePrecision(std::vector<std::pair<float, bool>> ranked, int objects) {
  if (objects <= 0) return std::numeric_limits<double>::quiet_NaN();
  std::stable_sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<double> precision(ranked.size());
  int tp = 0;
  for (size_t i = 0; i < ranked.size(); ++i) {
    tp += ranked[i].second;
    precision[i] = static_cast<double>(tp) / (i + 1);
  }
  // Precision envelope: the best precision at this recall or any higher one.
  for (size_t i = ranked.size(); i-- > 1;) precision[i - 1] = std::max(precision[i - 1], precision[i]);
  double ap = 0;
  for (size_t i = 0; i < ranked.size(); ++i) {
    if (ranked[i].second) ap += precision[i] / objects;  // each TP raises recall by 1/objects
  }
  return ap;
}

float rankingScore(const Hypothesis& h) { return h.confidence; }

namespace {

// Recall-precision points down a ranking, for the precision-recall curve.
std::vector<std::pair<double, double>> precisionRecall(std::vector<std::pair<float, bool>> ranked, int objects) {
  std::vector<std::pair<double, double>> curve;
  if (objects <= 0) return curve;
  std::stable_sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  int tp = 0;
  for (size_t i = 0; i < ranked.size(); ++i) {
    tp += ranked[i].second;
    curve.emplace_back(static_cast<double>(tp) / objects, static_cast<double>(tp) / static_cast<double>(i + 1));
  }
  return curve;
}

}  // namespace

ClassScorer::ClassScorer(const Model& model, const CategoryMapping& mapping) {
  for (const auto& category : model.categories) {
    radius_[category.name] = category.box.max_edge / 4;
    auto it = mapping.find(category.name);
    auto targets = it == mapping.end() ? std::vector<std::string>{category.name} : it->second;
    auto same = std::find_if(classes_.begin(), classes_.end(),
                             [&](const Class& c) { return c.gt_categories == targets; });
    if (same == classes_.end()) {
      classes_.push_back({targets, {category.name}});
    } else {
      same->model_categories.push_back(category.name);
    }
  }
}

std::array<int, 3> ClassScorer::addScene(const std::vector<GroundTruthObject>& objects,
                                         const std::vector<Hypothesis>& hypotheses,
                                         const Eigen::Matrix3f& to_gravity, float min_confidence,
                                         const std::string& scene_name) {
  std::array<int, 3> scene{0, 0, 0};
  for (Class& c : classes_) {
    std::vector<Eigen::Vector3f> centres;
    std::vector<UprightBox> boxes;
    for (const auto& o : objects) {
      if (!contains(c.gt_categories, o.category) && !contains(c.model_categories, o.category)) continue;
      centres.push_back(o.center);
      boxes.push_back({to_gravity * o.center, o.size, o.yaw});
    }
    std::vector<ScoredDetection> detections, all;
    const size_t first = c.candidates.size();  // this scene's detections are appended from here
    for (const Hypothesis& h : hypotheses) {
      if (!h.passed_selection || !contains(c.model_categories, h.category)) continue;
      all.push_back({rankingScore(h), h.support_centroid, radius_.at(h.category), uprightBoxOf(h.box, to_gravity)});
      if (h.confidence >= min_confidence) detections.push_back(all.back());
      ClassScore::Candidate candidate{scene_name, h.category, false, all.back().score, h.score, h.support};
      if (h.verification) {
        candidate.verified = true;
        candidate.fit = h.verification->fit();
        candidate.profile_distance = h.verification->profile_distance;
      }
      c.candidates.push_back(std::move(candidate));
    }
    const auto by_iou = matchDetectionsByIou(all, boxes, 0.25f);
    for (const UprightBox& box : boxes) {
      ClassScore::ObjectOutcome outcome{scene_name, 0, 0, std::numeric_limits<float>::infinity()};
      for (const ScoredDetection& d : all) {
        const float iou = intersectionOverUnion(d.box, box);
        if (iou > outcome.best_iou) outcome.best_iou = iou, outcome.best_iou_confidence = d.score;
        outcome.nearest_distance = std::min(outcome.nearest_distance, (d.box.center - box.center).norm());
      }
      c.outcomes.push_back(outcome);
    }
    for (size_t d = 0; d < all.size(); ++d) {
      c.candidates[first + d].tp25 = by_iou[d];
      if (all[d].score >= min_confidence) (by_iou[d] ? c.tp25 : c.fp25) += 1;
    }
    c.scenes += 1;
    const auto labels = matchDetections(detections, centres);
    int tp = 0, fp = 0;
    for (size_t d = 0; d < detections.size(); ++d) {
      if (labels[d] == MatchLabel::kMergedFalsePositive) continue;
      const bool is_tp = labels[d] == MatchLabel::kTruePositive;
      c.ranked.emplace_back(detections[d].score, is_tp);
      (is_tp ? tp : fp) += 1;
    }
    c.objects += static_cast<int>(centres.size());
    c.tp += tp;
    c.fp += fp;
    scene[0] += tp;
    scene[1] += fp;
    scene[2] += static_cast<int>(centres.size()) - tp;
  }
  return scene;
}

std::vector<ClassScore> ClassScorer::scores() const {
  std::vector<ClassScore> out;
  for (const Class& c : classes_) {
    ClassScore score;
    for (const auto& g : c.gt_categories) score.name += (score.name.empty() ? "" : "|") + g;
    score.model_categories = c.model_categories;
    score.objects = c.objects;
    score.tp = c.tp;
    score.fp = c.fp;
    score.fn = c.objects - c.tp;
    score.scenes = c.scenes;
    score.rate = ratio(c.tp, c.objects + c.fp);
    score.ap = averagePrecision(c.ranked, c.objects);
    for (const auto& d : c.candidates) score.ranked25.emplace_back(d.confidence, d.tp25);
    score.ap25 = averagePrecision(score.ranked25, c.objects);
    score.tp25 = c.tp25;
    score.fp25 = c.fp25;
    score.pr25 = precisionRecall(score.ranked25, c.objects);
    std::stable_sort(score.ranked25.begin(), score.ranked25.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    score.outcomes = c.outcomes;
    score.candidates = c.candidates;
    out.push_back(score);
  }
  return out;
}

Eigen::Vector3f givenUp(const AnnotatedScene& scene, const RealEvalParams& params) {
  const Eigen::Vector3f up = scene.to_gravity.row(2).transpose();
  if (params.up_tilt_deg == 0.0f) return up;
  const float tilt = params.up_tilt_deg * static_cast<float>(M_PI) / 180.0f;
  const float azimuth = params.up_tilt_azimuth_deg * static_cast<float>(M_PI) / 180.0f;
  const Eigen::Vector3f towards = std::cos(azimuth) * scene.to_gravity.row(0).transpose() +
                                  std::sin(azimuth) * scene.to_gravity.row(1).transpose();
  return (std::cos(tilt) * up + std::sin(tilt) * towards).normalized();
}

RealResult evaluateRealScenes(const Model& model, const std::vector<AnnotatedScene>& scenes,
                              const RealEvalParams& params) {
  if (params.strategies.empty()) throw Error(ErrorCode::kInvalidInput, "no recognition strategy to evaluate");
  std::vector<ClassScorer> scorers(params.strategies.size(), ClassScorer(model, params.mapping));
  RealResult result;
  for (const auto& s : params.strategies) result.combinations.push_back({s.name, {}, {}});

  for (const AnnotatedScene& annotation : scenes) {
    SceneRun run;
    run.name = annotation.name;
    auto start = std::chrono::steady_clock::now();
    Scene scene = loadCloudFile(annotation.cloud_path);
    run.load_ms = millisecondsSince(start);
    run.points = scene.cloud->size();
    // Gravity-levelled data says so, as a robot that knows its pose would; the others make the
    // gravity stage find the floor.
    if (annotation.up_is_given && params.give_up) scene.up = givenUp(annotation, params);
    if (params.viewpoint == ViewpointPolicy::kAuto) {
      ViewpointParams view;
      view.eye_height = params.eye_height;
      scene = lookedAt(scene, view);
    } else {
      scene.sensor_origin = sceneViewpoint(annotation, scene, params.viewpoint, params.eye_height);
    }
    run.viewpoint = scene.sensor_origin;

    start = std::chrono::steady_clock::now();
    FrontEndResult front = extractFeatures(scene, model.front_end, model.front_end.smoothing.enabled);
    run.front_end_ms = millisecondsSince(start);
    run.surface_points = front.surface_points;
    run.keypoints = front.features.size();

    double recognition_ms = 0;
    for (size_t s = 0; s < params.strategies.size(); ++s) {
      start = std::chrono::steady_clock::now();
      auto hypotheses = hypothesesForFeatures(model, front.features, params.strategies[s].strategy, params.recognition,
                                              &scene, params.more_models);
      run.recognition_ms.push_back(millisecondsSince(start));
      recognition_ms += run.recognition_ms.back();
      result.combinations[s].scene_tp_fp_fn.push_back(
          scorers[s].addScene(annotation.objects, hypotheses, annotation.to_gravity,
                              params.recognition.preset == RecognitionPreset::kSeed ? 0.0f
                                                                                    : params.recognition.min_confidence,
                              annotation.name));
    }
    if (params.progress) {
      std::ostringstream line;
      line.setf(std::ios::fixed);
      line.precision(0);
      line << "scene " << run.name << ": " << run.points << " points, " << run.keypoints << " keypoints, load "
           << run.load_ms << " ms, front end " << run.front_end_ms << " ms, recognition " << recognition_ms
           << " ms (" << params.strategies.size() << " combinations)";
      params.progress(line.str());
    }
    result.scenes.push_back(std::move(run));
  }
  for (size_t s = 0; s < params.strategies.size(); ++s) result.combinations[s].classes = scorers[s].scores();
  return result;
}

}  // namespace ism
