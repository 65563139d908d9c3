#include "core/training/calibration.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <numeric>
#include <optional>
#include <random>
#include <set>
#include <sstream>

#include <Eigen/Dense>

#include "core/common/error.h"
#include "core/common/upright_box.h"
#include "core/frontend/frontend.h"
#include "core/gravity/viewpoint.h"
#include "core/recognition/recognizer.h"
#include "core/recognition/scene_checks.h"
#include "core/recognition/suppression.h"
#include "core/recognition/top_extent.h"
#include "core/recognition/verification.h"
#include "core/scanner/scanner.h"
#include "core/training/background.h"
#include "core/training/discriminative_weights.h"
#include "core/training/newton.h"
#include "core/training/parallel_for.h"
#include "core/training/votes.h"

namespace ism {
namespace {

// A box of the room: a wall, a cabinet, a shelf. Things no furniture category is.
Mesh boxMesh(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
  Mesh mesh;
  for (int i = 0; i < 8; ++i) {
    mesh.vertices.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
  }
  const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : faces) {
    mesh.triangles.emplace_back(f[0], f[1], f[2]);
    mesh.triangles.emplace_back(f[0], f[2], f[3]);
  }
  return mesh;
}

// The model with the votes and the verification shapes of the training objects in `held_out` (per
// category, per model index) left out: what recognises the fold's rooms. The rooms show exactly
// those objects, and the world shows none of the training objects: fitting their own shapes
// would teach the calibration fits no real object reaches.
Model foldModel(const Model& model, const std::vector<std::vector<TrainingVote>>& votes,
                const std::vector<std::vector<bool>>& held_out) {
  Model fold;
  fold.front_end = model.front_end;
  fold.voting = model.voting;
  fold.trained_knn = model.trained_knn;
  fold.trained_cutoff = model.trained_cutoff;
  fold.global_codebook = model.global_codebook;
  for (size_t c = 0; c < model.categories.size(); ++c) {
    CategoryModel category = model.categories[c];
    category.own_codebook.reset();
    category.own_votes = {};
    category.calibration.reset();
    category.global_votes = packVotes(votes[c], model.global_codebook->size(), held_out[c]);
    category.global_votes.codeword_weights = model.categories[c].global_votes.codeword_weights;
    for (size_t m = 0; m < category.objects.size() && m < held_out[c].size(); ++m) {
      if (held_out[c][m]) category.objects[m].surface.clear();
    }
    fold.categories.push_back(std::move(category));
  }
  return fold;
}

}  // namespace

CalibrationRoom composeCalibrationRoom(const std::vector<const PlacedObject*>& furniture,
                                       const std::vector<const PlacedObject*>& background,
                                       const CalibrationParams& params, const NoiseParams& noise, std::mt19937& rng,
                                       const std::vector<const PlacedObject*>& tables) {
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  const auto uniform = [&](float lo, float hi) { return lo + (hi - lo) * unit(rng); };
  std::vector<SceneObject> objects;
  std::vector<std::pair<Eigen::Vector2f, float>> taken;  // footprint circles
  const auto place = [&](float radius, Eigen::Vector2f& at) {
    for (int attempt = 0; attempt < 50; ++attempt) {
      at = {uniform(-1.6f, 1.6f), uniform(-1.2f, 1.2f)};
      const bool free = std::all_of(taken.begin(), taken.end(), [&](const auto& t) {
        return (t.first - at).norm() > t.second + radius + 0.1f;
      });
      if (free) {
        taken.emplace_back(at, radius);
        return true;
      }
    }
    return false;
  };
  const auto pick = [&](const std::vector<const PlacedObject*>& from) -> const PlacedObject& {
    return *from[static_cast<size_t>(unit(rng) * static_cast<float>(from.size())) % from.size()];
  };
  // One of `from`, drawn at random, standing apart from the others at a random heading, as its
  // category's object or as clutter (""); false where no free place was found.
  const auto standOne = [&](const std::vector<const PlacedObject*>& from, bool clutter) {
    const PlacedObject& o = pick(from);
    const Eigen::Vector3f size = o.mesh->bounds().sizes();
    Eigen::Vector2f at;
    if (!place(0.5f * std::hypot(size.x(), size.y()), at)) return false;
    objects.push_back({clutter ? std::string() : o.category, *o.mesh, at.x(), at.y(), uniform(-3.1416f, 3.1416f)});
    return true;
  };
  // A table with others pulled up to it: `seated` (furniture that is not a table) at its sides,
  // its centre from the table's edge (half of it under the top) to half its depth out (just clear),
  // at a random heading (a mesh's front is not known), apart from each other.
  const auto standGroup = [&](const std::vector<const PlacedObject*>& seated) {
    const PlacedObject& table = pick(tables);
    const Eigen::Vector3f table_size = table.mesh->bounds().sizes();
    Eigen::Vector2f at;
    if (!place(0.5f * std::hypot(table_size.x(), table_size.y()), at)) return false;
    const float table_yaw = uniform(-3.1416f, 3.1416f);
    objects.push_back({table.category, *table.mesh, at.x(), at.y(), table_yaw});
    const Eigen::Rotation2Df to_room(table_yaw);
    std::vector<std::pair<Eigen::Vector2f, float>> members;  // the group's own, closer than `taken` stands things
    const int count = 1 + static_cast<int>(unit(rng) * static_cast<float>(params.max_grouped));
    for (int i = 0; i < count; ++i) {
      const PlacedObject& o = pick(seated);
      const Eigen::Vector3f size = o.mesh->bounds().sizes();
      const float depth = 0.5f * std::min(size.x(), size.y());
      for (int attempt = 0; attempt < 20; ++attempt) {
        const int side = static_cast<int>(unit(rng) * 4.0f) % 4;  // +x, -x, +y, -y of the table
        const float across = 0.5f * table_size[side / 2] + uniform(0.0f, 1.0f) * depth;
        const float along = uniform(-0.5f, 0.5f) * table_size[1 - side / 2];
        Eigen::Vector2f local = side / 2 == 0 ? Eigen::Vector2f(across, along) : Eigen::Vector2f(along, across);
        if (side % 2 == 1) local = -local;
        const Eigen::Vector2f spot = at + to_room * local;
        const bool free = std::all_of(members.begin(), members.end(), [&](const auto& m) {
          return (m.first - spot).norm() > m.second + depth + 0.05f;
        });
        if (!free) continue;
        members.emplace_back(spot, depth);
        taken.emplace_back(spot, 0.5f * std::hypot(size.x(), size.y()));
        objects.push_back({o.category, *o.mesh, spot.x(), spot.y(), uniform(-3.1416f, 3.1416f)});
        break;
      }
    }
    return true;
  };
  CalibrationRoom room;
  std::vector<const PlacedObject*> seated;
  for (const PlacedObject* o : furniture) {
    if (std::find(tables.begin(), tables.end(), o) == tables.end()) seated.push_back(o);
  }
  // Drawn only where groups can be, so that rooms without them stay as they were.
  const bool grouped = params.grouped_rooms > 0 && !tables.empty() && !seated.empty() && unit(rng) < params.grouped_rooms;
  if (grouped && standGroup(seated)) {
    for (size_t i = 0; i < objects.size(); ++i) room.categories.push_back(objects[i].category);
  } else {
    const int count = 1 + static_cast<int>(unit(rng) * static_cast<float>(params.max_objects));
    for (int i = 0; i < std::min<int>(count, static_cast<int>(furniture.size())); ++i) {
      if (standOne(furniture, false)) room.categories.push_back(objects.back().category);
    }
  }
  // Walls at the room's far side and one side, shelves and cabinets against or near them.
  objects.push_back({"", boxMesh({-3.5f, 2.2f, 0}, {3.5f, 2.3f, 2.5f}), 0, 0, 0});
  if (unit(rng) < 0.5f) objects.push_back({"", boxMesh({-3.5f, -4.0f, 0}, {-3.4f, 2.3f, 2.5f}), 0, 0, 0});
  const int boxes = static_cast<int>(unit(rng) * static_cast<float>(params.clutter_boxes + 1));
  for (int i = 0; i < boxes; ++i) {
    const Eigen::Vector3f size(uniform(0.2f, 1.2f), uniform(0.2f, 0.6f), uniform(0.2f, 2.0f));
    Eigen::Vector2f at;
    if (!place(0.5f * std::hypot(size.x(), size.y()), at)) continue;
    objects.push_back({"", boxMesh(-size.cwiseProduct(Eigen::Vector3f(0.5f, 0.5f, 0)), size.cwiseProduct(Eigen::Vector3f(0.5f, 0.5f, 1))),
                       at.x(), at.y(), uniform(-3.1416f, 3.1416f)});
  }
  const int others = background.empty() ? 0 : static_cast<int>(unit(rng) * static_cast<float>(params.background_objects + 1));
  for (int i = 0; i < others; ++i) standOne(background, true);
  SyntheticSceneParams scene;
  const float azimuth = uniform(-2.4f, -0.7f);  // from the open side, facing the far wall
  const float distance = uniform(params.distance_min, params.distance_max);
  scene.camera_eye = {distance * std::cos(azimuth), distance * std::sin(azimuth),
                      uniform(params.camera_height_min, params.camera_height_max)};
  scene.camera_target = {uniform(-0.5f, 0.5f), uniform(-0.5f, 0.5f), uniform(0.2f, 0.6f)};
  scene.floor_size = 8.0f;
  scene.noise = noise;  // the training scans' sensor
  scene.noise.seed = static_cast<uint32_t>(rng());
  room.scene = composeScene(objects, scene);
  room.objects = std::move(objects);
  room.view = scene;
  return room;
}

Scene calibrationMap(const CalibrationRoom& room, const CalibrationParams& params, std::mt19937& rng) {
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  const auto uniform = [&](float lo, float hi) { return lo + (hi - lo) * unit(rng); };
  // The room composeCalibrationRoom builds: its furniture and clutter within 1.6 x 1.2 m of the
  // middle, the far wall at y = 2.2 m, the side wall (where there is one) at x = -3.4 m.
  const auto inside = [](const Eigen::Vector3f& p) { return std::abs(p.x()) <= 3.5f && p.y() >= -3.0f && p.y() <= 2.3f; };
  std::vector<Eigen::Vector3f> points;
  const int views = std::max(1, params.map_views);
  const float start = uniform(-3.1416f, 3.1416f);
  for (int v = 0; v < views; ++v) {
    // Walking around the furniture, beyond its footprint, looking at it.
    const float azimuth = start + 6.2832f * static_cast<float>(v) / static_cast<float>(views) + uniform(-0.3f, 0.3f);
    const float distance = uniform(2.0f, 3.0f);
    SyntheticSceneParams view = room.view;
    view.camera_eye = {std::max(distance * std::cos(azimuth), -3.2f), std::min(distance * std::sin(azimuth), 2.0f),
                       uniform(1.0f, 1.8f)};
    view.camera_target = {uniform(-1.0f, 1.0f), uniform(-0.8f, 0.8f), uniform(0.2f, 0.6f)};
    view.noise.seed = static_cast<uint32_t>(rng());
    const SyntheticScene seen = composeScene(room.objects, view);
    for (const auto& p : seen.scene.cloud->points) {
      if (inside(p.getVector3fMap())) points.push_back(p.getVector3fMap());
    }
  }
  Scene map = fusedCloud(points, params.map_spacing, Eigen::Vector3f::Zero(), "calibration room (map)");
  const float lo = std::log(static_cast<float>(std::max(1, params.map_points_min)));
  const float hi = std::log(static_cast<float>(std::max(params.map_points_min, params.map_points_max)));
  const auto wanted = static_cast<size_t>(std::exp(uniform(lo, hi)));
  if (map.cloud->size() > wanted) {
    Cloud::Ptr kept(new Cloud);
    kept->reserve(wanted);
    std::vector<size_t> order(map.cloud->size());
    std::iota(order.begin(), order.end(), size_t{0});
    std::shuffle(order.begin(), order.end(), rng);
    order.resize(wanted);
    std::sort(order.begin(), order.end());
    for (const size_t i : order) kept->push_back((*map.cloud)[i]);
    map.cloud = kept;
  }
  // No pose, as a map is sent: recognition makes up its viewpoint (lookedAt).
  map.sensor_origin = Eigen::Vector3f::Zero();
  map.cloud->sensor_origin_.setZero();
  return map;
}

std::string categoryKind(const std::string& category) {
  const size_t last = category.rfind('_');
  return last == std::string::npos ? category : category.substr(last + 1);
}

PeakLabel labelPeak(const Hypothesis& peak, const std::vector<std::string>& categories,
                    const std::vector<GroundTruthObject>& objects, const Eigen::Matrix3f& to_gravity, bool kinds,
                    std::vector<bool>& matched) {
  const std::string& category = peak.category;
  const UprightBox peak_box = uprightBoxOf(peak.box, to_gravity);
  // The evaluation's rules: the centre within a quarter of the object's longest side, or the
  // boxes overlapping by a quarter.
  const auto on = [&](size_t o) {
    const GroundTruthObject& truth = objects[o];
    const Eigen::Vector2f offset = (to_gravity * (peak.center - truth.center)).head<2>();
    const UprightBox box{to_gravity * truth.center, truth.size, truth.yaw};
    return offset.norm() <= truth.size.maxCoeff() / 4 || intersectionOverUnion(peak_box, box) >= 0.25f;
  };
  for (size_t o = 0; o < categories.size(); ++o) {
    if (!matched[o] && categories[o] == category && on(o)) {
      matched[o] = true;
      return PeakLabel::kPositive;
    }
  }
  if (kinds) {
    const std::string kind = categoryKind(category);
    for (size_t o = 0; o < categories.size(); ++o) {
      if (!categories[o].empty() && categories[o] != category && categoryKind(categories[o]) == kind && on(o)) {
        return PeakLabel::kLeftOut;
      }
    }
  }
  return PeakLabel::kNegative;
}

namespace {

// The room's frame as an unorganized cloud: a random `fraction` of its points, no image grid.
Scene pointSample(const Scene& frame, float fraction, std::mt19937& rng) {
  Scene sample;
  sample.has_color = frame.has_color;
  sample.sensor_origin = frame.sensor_origin;
  sample.sensor_orientation = frame.sensor_orientation;
  sample.source = frame.source + " (point sample)";
  sample.up = frame.up;
  std::bernoulli_distribution keep(fraction);
  for (const auto& p : frame.cloud->points) {
    if (keep(rng)) sample.cloud->push_back(p);
  }
  return sample;
}

// Labels one room's peaks, category by category, as labelPeak does, most confident first.
// `checks`: each category's scene checks, or empty to label every verified peak. `nearest`: each
// keypoint's nearest global codeword (-1 unknown), which a sample keeps for its supporting keypoints.
void labelPeaks(const Model& model, const CalibrationRoom& room, std::vector<Hypothesis> peaks, const Eigen::Matrix3f& to_gravity,
                const VerificationScene& view, bool cloud, const VerificationParams& verification,
                const std::vector<SceneChecks>& checks, bool kinds, std::vector<CalibrationSample>& out,
                const std::vector<int>& nearest) {
  for (size_t c = 0; c < model.categories.size(); ++c) {
    const std::string& name = model.categories[c].name;
    std::vector<Hypothesis> own;
    for (const auto& p : peaks) {
      if (p.category == name) own.push_back(p);
    }
    SuppressionParams suppression;
    suppression.merge_support = false;  // as recognition merges before the confidence
    own = suppressOverlaps(std::move(own), to_gravity, suppression);  // one per object, as recognition keeps
    verifyHypotheses(view, model, own, verification);
    own.erase(std::remove_if(own.begin(), own.end(),
                             [](const Hypothesis& h) { return h.verification && h.verification->duplicate(); }),
              own.end());
    if (!checks.empty()) {
      // What recognition would reject or refute never answers, so it is no sample of what an
      // answer's confidence means; a rejected peak does not take its object from the next one.
      own.erase(std::remove_if(own.begin(), own.end(),
                               [&](Hypothesis& h) { return checks[c](view, h, to_gravity) != SceneVerdict::kKept; }),
                own.end());
    }
    std::vector<bool> matched(room.categories.size(), false);
    for (const auto& p : own) {  // most confident, i.e. highest score, first
      const PeakLabel label = labelPeak(p, room.categories, room.scene.objects, to_gravity, kinds, matched);
      if (label == PeakLabel::kLeftOut) continue;
      const bool positive = label == PeakLabel::kPositive;
      CalibrationSample& sample = out.emplace_back();
      sample.category = static_cast<int>(c);
      sample.score = p.score;
      sample.support = p.support;
      for (int k : p.support_indices) {
        if (k >= 0 && static_cast<size_t>(k) < nearest.size()) sample.codewords.push_back(nearest[static_cast<size_t>(k)]);
      }
      sample.positive = positive;
      sample.cloud = cloud;
      if (p.verification) {
        sample.fit = p.verification->fit();
        sample.profile_distance = p.verification->profile_distance;
      }
    }
  }
}

}  // namespace

std::vector<CalibrationSample> calibrationSamples(const Model& model, const std::vector<TrainingScan>& scans,
                                                  const std::vector<PlacedObject>& objects,
                                                  const TrainingParams& params) {
  if (!model.global_codebook) throw Error(ErrorCode::kInvalidInput, "calibration needs the global codebook");
  const CalibrationParams& cp = params.calibration;
  if (cp.folds < 2) throw Error(ErrorCode::kInvalidInput, "calibration needs at least 2 folds");
  std::vector<std::vector<TrainingVote>> votes(model.categories.size());
  std::vector<int> models(model.categories.size(), 0);
  for (size_t c = 0; c < model.categories.size(); ++c) {
    std::vector<const TrainingScan*> own;
    for (const auto& s : scans) {
      if (s.category == model.categories[c].name) own.push_back(&s);
    }
    votes[c] = trainingVotes(own, *model.global_codebook, model.voting.frame);
    models[c] = model.categories[c].training_models;
  }
  Strategy strategy{CodebookType::kGlobal, model.trained_knn, VoteWeighting::kLocalization};
  std::vector<CalibrationSample> samples;
  std::mutex mutex;
  std::vector<const PlacedObject*> background;  // every fold's rooms stand them among the clutter
  for (const auto& o : objects) {
    if (o.category == kBackgroundCategory) background.push_back(&o);
  }
  // Tables (flat-topped categories, top_extent.h) that grouped rooms pull the other furniture up to.
  std::vector<bool> table_category(model.categories.size(), false);
  if (cp.grouped_rooms > 0) {
    for (size_t c = 0; c < model.categories.size(); ++c) table_category[c] = flatTopped(model.categories[c]);
  }
  for (int fold = 0; fold < cp.folds; ++fold) {
    // A category's fold holds models m with m % folds == fold, unless that would leave it none.
    std::vector<std::vector<bool>> held_out(model.categories.size());
    std::vector<const PlacedObject*> candidates, tables;
    for (size_t c = 0; c < model.categories.size(); ++c) {
      held_out[c].assign(static_cast<size_t>(models[c]), false);
      for (int m = fold; m < models[c]; m += cp.folds) held_out[c][static_cast<size_t>(m)] = true;
      if (std::count(held_out[c].begin(), held_out[c].end(), false) == 0) std::fill(held_out[c].begin(), held_out[c].end(), false);
    }
    for (const auto& o : objects) {
      const CategoryModel* c = model.find(o.category);
      if (c == nullptr) continue;
      const auto index = static_cast<size_t>(c - model.categories.data());
      if (static_cast<size_t>(o.model_index) < held_out[index].size() && held_out[index][static_cast<size_t>(o.model_index)]) {
        candidates.push_back(&o);
        if (table_category[index]) tables.push_back(&o);
      }
    }
    if (candidates.empty()) continue;
    const Model fold_model = foldModel(model, votes, held_out);
    std::vector<SceneChecks> checks;  // what they need from the fold's shapes, worked out once
    if (cp.scene_checks) {
      checks.reserve(fold_model.categories.size());
      for (const auto& category : fold_model.categories) checks.emplace_back(fold_model, category, cp.checks);
    }
    RecognitionOptions options;
    options.strategy = strategy;
    options.min_confidence = 0;
    options.one_answer_per_object = false;
    options.peak_centre = cp.peak_centre;
    VerificationParams verification;
    verification.fit_terms = cp.fit_terms;
    parallelFor(cp.rooms_per_fold, trainingThreads(params.threads), [&](int r) {
      std::mt19937 rng(cp.seed + static_cast<uint32_t>(fold * 100003 + r));
      const CalibrationRoom room = composeCalibrationRoom(candidates, background, cp, params.noise, rng, tables);
      if (room.scene.scene.cloud->size() < 1000) return;  // the camera saw next to nothing
      std::vector<CalibrationSample> found;
      const auto look = [&](const Scene& scene, bool cloud) {
        const Features features = extractFeatures(scene, fold_model.front_end, false).features;
        const VerificationScene view = makeVerificationScene(scene, features.gravity);
        std::vector<int> nearest;  // what learnCodewordFactors reads; empty: samples keep no codewords
        if (cp.learned_weights.enabled) {
          nearest.assign(features.size(), -1);
          for (const auto& a : fold_model.global_codebook->activate(features.descriptors, ActivationParams{})) {
            if (nearest[static_cast<size_t>(a.keypoint)] < 0) nearest[static_cast<size_t>(a.keypoint)] = a.codeword;
          }
        }
        for (size_t c = 0; c < fold_model.categories.size(); ++c) {
          RecognitionOptions category_options = options;
          category_options.categories = {fold_model.categories[c].name};
          const auto t = fold_model.categories[c].thresholds.find({CodebookType::kGlobal, strategy.activation.strategy,
                                                                   VoteWeighting::kLocalization});
          if (t == fold_model.categories[c].thresholds.end()) continue;
          category_options.min_score = cp.lowest_score_fraction * t->second;
          category_options.verify = false;  // labelPeaks verifies what recognition's suppression keeps
          auto peaks = recognizeFeatures(fold_model, features, category_options).hypotheses;
          const Eigen::Matrix3f to_gravity = features.gravity ? features.gravity->toGravity() : Eigen::Matrix3f::Identity();
          labelPeaks(fold_model, room, std::move(peaks), to_gravity, view, cloud, verification, checks, cp.kinds,
                     found, nearest);
        }
      };
      look(room.scene.scene, false);
      if (cp.clouds) {
        const float lo = std::log(cp.cloud_fraction_min), hi = std::log(cp.cloud_fraction_max);
        const float fraction = std::exp(lo + (hi - lo) * std::uniform_real_distribution<float>(0.0f, 1.0f)(rng));
        const Scene sample = pointSample(room.scene.scene, fraction, rng);
        if (sample.cloud->size() >= 100) look(sample, true);
      }
      if (cp.maps) {  // drawn last, so that the frame's and the point sample's draws do not depend on it
        const Scene map = lookedAt(calibrationMap(room, cp, rng));
        if (map.cloud->size() >= 100 && isMap(map)) look(map, true);
      }
      for (auto& s : found) s.fold = fold;
      std::lock_guard<std::mutex> lock(mutex);
      samples.insert(samples.end(), found.begin(), found.end());
    });
  }
  // The threads' order, not the rooms', put them in this order: the fits' sums then do not depend on it.
  std::sort(samples.begin(), samples.end(), [](const CalibrationSample& x, const CalibrationSample& y) {
    return std::tie(x.fold, x.cloud, x.category, x.score, x.support, x.positive, x.fit, x.profile_distance) <
           std::tie(y.fold, y.cloud, y.category, y.score, y.support, y.positive, y.fit, y.profile_distance);
  });
  return samples;
}

Eigen::Vector4d calibrationInputs(const CalibrationSample& s, bool shape_profile) {
  const double score = std::max(static_cast<double>(s.score), 1e-9);
  Eigen::Vector4d f;
  f << std::log(score), std::log(score / std::max(s.support, 1)), static_cast<double>(s.fit),
      shape_profile ? static_cast<double>(s.profile_distance) : 0.0;
  return f;
}

namespace {

constexpr int kSlopes = 4;  // ln s, ln(s / support), fit, profile distance: calibrationInputs
// A little ridge on the slopes (not on the intercepts) keeps a separable set finite.
constexpr double kRidge = 1e-3;

constexpr int kProfile = 3;  // the profile distance's slope
using Slopes = Eigen::Matrix<double, kSlopes, 1>;

// Logistic regression by Newton's method on the mean log-loss, each step halved until the loss
// falls, plus 0.5 * sum_j ridge_j w_j^2 + 0.5 * sum_j prior_j (w_j - mean_j)^2.
Eigen::VectorXd logistic(const std::vector<Eigen::VectorXd>& x, const std::vector<double>& y, const Eigen::VectorXd& ridge,
                         const Eigen::VectorXd& prior, const Eigen::VectorXd& mean, Eigen::VectorXd w) {
  const double n = static_cast<double>(x.size());
  const auto penalty = [&](const Eigen::VectorXd& v) {
    return 0.5 * v.dot(ridge.cwiseProduct(v)) + 0.5 * (v - mean).dot(prior.cwiseProduct(v - mean));
  };
  const auto loss = [&](const Eigen::VectorXd& v) {
    double sum = 0;
    for (size_t i = 0; i < x.size(); ++i) {
      const double z = v.dot(x[i]);
      const double m = y[i] > 0 ? -z : z;  // log(1 + exp(m)), without overflow
      sum += m > 0 ? m + std::log1p(std::exp(-m)) : std::log1p(std::exp(m));
    }
    return sum / n + penalty(v);
  };
  const auto derivatives = [&](const Eigen::VectorXd& v, Eigen::VectorXd& gradient, Eigen::MatrixXd& hessian) {
    gradient = ridge.cwiseProduct(v) + prior.cwiseProduct(v - mean);
    hessian = Eigen::MatrixXd((ridge + prior).asDiagonal());
    hessian.diagonal().array() += 1e-9;
    for (size_t i = 0; i < x.size(); ++i) {
      const double p = 1.0 / (1.0 + std::exp(-v.dot(x[i])));
      gradient += (p - y[i]) / n * x[i];
      hessian.noalias() += p * (1 - p) / n * x[i] * x[i].transpose();
    }
  };
  return newtonMinimise(std::move(w), loss, derivatives, 100, 1e-12);
}

void countLabels(const std::vector<CalibrationSample>& samples, Calibration& fit) {
  for (const auto& s : samples) (s.positive ? fit.positives : fit.negatives) += 1;
  if (fit.positives == 0 || fit.negatives == 0) {
    throw Error(ErrorCode::kInvalidInput, "calibration needs positive and negative peaks, got " +
                                              std::to_string(fit.positives) + " and " + std::to_string(fit.negatives));
  }
}

// One category's fit; with `pooled`, its slopes have a Gaussian prior of spread `spread` around
// those (the prior's weight per sample falls as 1 / n, as a prior's does against a likelihood).
Calibration fitOne(const std::vector<CalibrationSample>& samples, bool shape_profile,
                   const std::optional<Slopes>& pooled, double spread) {
  Calibration fit;
  countLabels(samples, fit);
  // Features (ln s, ln(s / n), fit, profile distance, 1); weights (a, c, d, e, b). Without the
  // profile its feature is 0, and the ridge alone holds e at 0.
  std::vector<Eigen::VectorXd> x;
  std::vector<double> y;
  for (const auto& s : samples) {
    Eigen::VectorXd row(kSlopes + 1);
    row << calibrationInputs(s, shape_profile), 1.0;
    x.push_back(row);
    y.push_back(s.positive ? 1.0 : 0.0);
  }
  Eigen::VectorXd ridge = Eigen::VectorXd::Constant(kSlopes + 1, kRidge), prior = Eigen::VectorXd::Zero(kSlopes + 1),
                  mean = Eigen::VectorXd::Zero(kSlopes + 1);
  ridge[kSlopes] = 0;
  if (pooled) {
    const double weight = 1.0 / (spread * spread * static_cast<double>(samples.size()));
    for (int j = 0; j < kSlopes; ++j) {
      if (j == kProfile && !shape_profile) continue;
      prior[j] = weight;
      mean[j] = (*pooled)[j];
    }
  }
  Eigen::VectorXd start = Eigen::VectorXd::Zero(kSlopes + 1);
  start[0] = 1;
  const Eigen::VectorXd w = logistic(x, y, ridge, prior, mean, start);
  fit.a = static_cast<float>(w[0]);
  fit.c = static_cast<float>(w[1]);
  fit.d = static_cast<float>(w[2]);
  fit.e = static_cast<float>(w[3]);
  fit.b = static_cast<float>(w[4]);
  return fit;
}

// The slopes every category shares, each category with its own intercept: one logistic
// regression over all of `groups` (each a category's samples and whether it weighs the profile).
Slopes pooledSlopes(const std::vector<std::pair<const std::vector<CalibrationSample>*, bool>>& groups) {
  const int dims = kSlopes + static_cast<int>(groups.size());
  std::vector<Eigen::VectorXd> x;
  std::vector<double> y;
  for (size_t g = 0; g < groups.size(); ++g) {
    for (const auto& s : *groups[g].first) {
      Eigen::VectorXd row = Eigen::VectorXd::Zero(dims);
      row.head<kSlopes>() = calibrationInputs(s, groups[g].second);
      row[kSlopes + static_cast<int>(g)] = 1.0;
      x.push_back(row);
      y.push_back(s.positive ? 1.0 : 0.0);
    }
  }
  Eigen::VectorXd ridge = Eigen::VectorXd::Zero(dims);
  ridge.head<kSlopes>().setConstant(kRidge);
  Eigen::VectorXd start = Eigen::VectorXd::Zero(dims);
  start[0] = 1;
  const Eigen::VectorXd w = logistic(x, y, ridge, Eigen::VectorXd::Zero(dims), Eigen::VectorXd::Zero(dims), start);
  return w.head<kSlopes>();
}

bool hasBothLabels(const std::vector<CalibrationSample>& samples) {
  const auto positives = std::count_if(samples.begin(), samples.end(), [](const auto& s) { return s.positive; });
  return positives > 0 && positives < static_cast<std::ptrdiff_t>(samples.size());
}

// The slopes the groups with both labels share; none with fewer than two such groups.
std::optional<Slopes> sharedSlopes(const std::vector<std::vector<CalibrationSample>>& groups, const std::vector<bool>& profiles) {
  std::vector<std::pair<const std::vector<CalibrationSample>*, bool>> usable;
  for (size_t g = 0; g < groups.size(); ++g) {
    if (hasBothLabels(groups[g])) usable.emplace_back(&groups[g], profiles[g]);
  }
  if (usable.size() < 2) return std::nullopt;
  return pooledSlopes(usable);
}

// Fits each group, alone (spread 0 or no shared slopes) or drawn towards `shared`.
std::vector<std::optional<Calibration>> fitGroups(const std::vector<std::vector<CalibrationSample>>& groups,
                                                  const std::vector<bool>& profiles, const std::optional<Slopes>& shared,
                                                  double spread) {
  const std::optional<Slopes> towards = spread > 0 ? shared : std::nullopt;
  std::vector<std::optional<Calibration>> fits(groups.size());
  for (size_t g = 0; g < groups.size(); ++g) {
    if (hasBothLabels(groups[g])) fits[g] = fitOne(groups[g], profiles[g], towards, spread);
  }
  return fits;
}

double logLoss(const Calibration& fit, const CalibrationSample& s) {
  const double p = std::clamp(static_cast<double>(fit.confidence(s.score, s.support, s.fit, s.profile_distance)), 1e-6, 1 - 1e-6);
  return s.positive ? -std::log(p) : -std::log(1 - p);
}

}  // namespace

Calibration fitCalibration(const std::vector<CalibrationSample>& samples, bool shape_profile) {
  return fitOne(samples, shape_profile, std::nullopt, 0);
}

std::vector<std::optional<Calibration>> fitCalibrations(const std::vector<std::vector<CalibrationSample>>& groups,
                                                        const std::vector<bool>& profiles, const std::vector<double>& spreads,
                                                        double* chosen) {
  double best_spread = spreads.empty() ? 0.0 : spreads.front();
  if (spreads.size() > 1) {
    // Leave one fold of rooms out: the spread whose fits on the other folds' rooms best predict
    // its rooms, which hold furniture those fits never saw. The folds' splits and shared slopes
    // do not depend on the spread.
    std::set<int> folds;
    for (const auto& g : groups) {
      for (const auto& s : g) folds.insert(s.fold);
    }
    struct Split {
      std::vector<std::vector<CalibrationSample>> train, test;
      std::optional<Slopes> shared;
    };
    std::vector<Split> splits;
    for (const int fold : folds) {
      Split& split = splits.emplace_back();
      split.train.resize(groups.size());
      split.test.resize(groups.size());
      for (size_t g = 0; g < groups.size(); ++g) {
        for (const auto& s : groups[g]) (s.fold == fold ? split.test : split.train)[g].push_back(s);
      }
      split.shared = sharedSlopes(split.train, profiles);
    }
    double best = std::numeric_limits<double>::infinity();
    for (const double spread : spreads) {
      double total = 0;  // a group without both labels in a fold's training rooms counts for no spread
      for (const Split& split : splits) {
        const auto fits = fitGroups(split.train, profiles, split.shared, spread);
        for (size_t g = 0; g < groups.size(); ++g) {
          if (!fits[g]) continue;
          for (const auto& s : split.test[g]) total += logLoss(*fits[g], s);
        }
      }
      if (total < best) {
        best = total;
        best_spread = spread;
      }
    }
  }
  if (chosen != nullptr) *chosen = best_spread;
  return fitGroups(groups, profiles, best_spread > 0 ? sharedSlopes(groups, profiles) : std::nullopt, best_spread);
}

void calibrate(Model& model, const std::vector<TrainingScan>& scans, const std::vector<PlacedObject>& objects,
               const TrainingParams& params) {
  std::vector<CalibrationSample> samples = calibrationSamples(model, scans, objects, params);
  const size_t categories = model.categories.size();
  if (params.calibration.learned_weights.enabled) {
    const auto factors =
        learnCodewordFactors(samples, categories, model.global_codebook->size(), params.calibration.learned_weights);
    applyCodewordFactors(model, factors);
    if (params.progress) {
      for (size_t c = 0; c < categories; ++c) params.progress(describeFactors(model.categories[c].name, factors[c]));
    }
    // The confidence is fitted on rooms the weights were not learned from.
    TrainingParams again = params;
    again.calibration.seed = params.calibration.seed * 7919u + 11u;
    samples = calibrationSamples(model, scans, objects, again);
  }
  // A flat-topped category's box is the top the scene measured (top_extent.h), not its fitted
  // shape's: tables come in every length and carry what stands on and under them, so the profile
  // in a training table's box would judge the box rather than the table.
  std::vector<bool> profiles(categories);
  for (size_t c = 0; c < categories; ++c) profiles[c] = params.calibration.shape_profile && !flatTopped(model.categories[c]);
  std::vector<double> spreads;
  if (params.calibration.pooled) spreads = params.calibration.pooling_spreads;
  // The frames' samples, then the point samples': each category's, and its fit.
  std::vector<std::vector<CalibrationSample>> groups[2];
  std::vector<std::optional<Calibration>> fits[2];
  for (const bool cloud : {false, true}) {
    auto& own = groups[cloud];
    own.resize(categories);
    for (const auto& s : samples) {
      if (s.cloud == cloud && s.category >= 0 && static_cast<size_t>(s.category) < categories) {
        own[static_cast<size_t>(s.category)].push_back(s);
      }
    }
    double spread = 0;
    fits[cloud] = fitCalibrations(own, profiles, spreads, &spread);
    if (params.progress && !spreads.empty()) {
      std::ostringstream line;
      line << (cloud ? "calibration for clouds" : "calibration") << ": slopes drawn towards the categories' shared ones, spread "
           << spread << " (of";
      for (const double s : spreads) line << " " << s;
      line << "; 0 fits each alone)";
      params.progress(line.str());
    }
  }
  const bool point_samples = std::any_of(groups[1].begin(), groups[1].end(), [](const auto& g) { return !g.empty(); });
  for (size_t c = 0; c < categories; ++c) {
    CategoryModel& category = model.categories[c];
    const auto t = category.thresholds.find({CodebookType::kGlobal, model.trained_knn.strategy, VoteWeighting::kLocalization});
    for (const bool cloud : {false, true}) {
      std::optional<Calibration>& slot = cloud ? category.cloud_calibration : category.calibration;
      if (cloud && !point_samples) {  // point samples not asked for
        slot.reset();
        continue;
      }
      std::ostringstream line;
      line.setf(std::ios::fixed);
      line.precision(3);
      line << category.name << (cloud ? " calibration for clouds: " : " calibration: ");
      try {
        Calibration fit;
        if (!fits[cloud][c]) countLabels(groups[cloud][c], fit);  // throws, naming what is missing
        fit = *fits[cloud][c];
        if (!(fit.a + fit.c > 0)) throw Error(ErrorCode::kInvalidInput, "the fitted confidence falls with the score");
        fit.min_score = t == category.thresholds.end() ? 0.0f : params.calibration.lowest_score_fraction * t->second;
        slot = fit;
        line << "ln s " << fit.a << ", ln(s / support) " << fit.c  << ", fit " << fit.d << ", profile distance " << fit.e << ", bias " << fit.b << " ("
             << fit.positives << " positive and " << fit.negatives << " negative peaks)";
      } catch (const Error& e) {
        slot.reset();
        line << "none (" << e.what() << ")";
      }
      if (params.progress) params.progress(line.str());
    }
  }
  if (params.calibration_samples) params.calibration_samples(model, samples);
}

}  // namespace ism
