#include "core/training/trainer.h"

#include "core/common/version.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <map>
#include <mutex>
#include <sstream>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/common/error.h"
#include "core/frontend/frontend.h"
#include "core/recognition/box_selection.h"
#include "core/training/background.h"
#include "core/training/calibration.h"
#include "core/training/leave_one_out.h"
#include "core/training/parallel_for.h"
#include "core/training/statistics.h"
#include "core/training/votes.h"

namespace ism {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::string fixed(double value, int digits) {
  std::ostringstream s;
  s.precision(digits);
  s << std::fixed << value;
  return s.str();
}

int threadCount(const TrainingParams& params) { return trainingThreads(params.threads); }

DescriptorMatrix stackDescriptors(const std::vector<const TrainingScan*>& scans) {
  Eigen::Index rows = 0, cols = 0;
  for (const auto* s : scans) {
    rows += s->features.descriptors.rows();
    if (s->features.size() > 0) cols = s->features.descriptors.cols();
  }
  DescriptorMatrix all(rows, cols);
  Eigen::Index at = 0;
  for (const auto* s : scans) {
    all.middleRows(at, s->features.descriptors.rows()) = s->features.descriptors;
    at += s->features.descriptors.rows();
  }
  return all;
}

std::string utcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buffer[32];
  std::strftime(buffer, sizeof buffer, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buffer;
}

// The scans of one category, in scan order, and how many models they come from.
struct CategoryScans {
  std::vector<const TrainingScan*> scans;
  int models = 0;  // 1 + the largest model_index
};

void checkTrainingParams(const std::vector<std::string>& categories, const TrainingParams& params) {
  if (categories.empty()) throw Error(ErrorCode::kInvalidInput, "training: no categories");
  if (!(params.threshold_floor >= 0 && params.threshold_floor <= 1)) {
    throw Error(ErrorCode::kInvalidInput,
                "training: threshold_floor " + std::to_string(params.threshold_floor) + " is not in [0, 1]");
  }
  if (!params.global_codebook && !params.separated_codebooks) {
    throw Error(ErrorCode::kInvalidInput, "training: neither a global nor separated codebooks requested");
  }
}

// The scans of each of `categories`, in that order. Throws for a category listed twice and for
// a scan of a category not listed.
std::vector<CategoryScans> scansByCategory(const std::vector<TrainingScan>& scans,
                                           const std::vector<std::string>& categories) {
  std::map<std::string, int> index_of;
  for (size_t c = 0; c < categories.size(); ++c) {
    if (!index_of.emplace(categories[c], static_cast<int>(c)).second) {
      throw Error(ErrorCode::kInvalidInput, "training: category '" + categories[c] + "' is listed twice");
    }
  }
  std::vector<CategoryScans> by_category(categories.size());
  for (const auto& scan : scans) {
    const auto it = index_of.find(scan.category);
    if (it == index_of.end()) throw Error(ErrorCode::kInvalidInput, "training: scan of unlisted category '" + scan.category + "'");
    CategoryScans& category = by_category[static_cast<size_t>(it->second)];
    category.scans.push_back(&scan);
    category.models = std::max(category.models, scan.model_index + 1);
  }
  return by_category;
}

// Box limits from the single-view keypoint boxes, which is what a hypothesis' support is: the
// smallest and largest volume and the largest edge seen, widened by one standard deviation.
BoxStats keypointBoxStats(const std::vector<const TrainingScan*>& scans) {
  std::vector<double> volumes, edges;
  for (const auto* s : scans) {
    if (s->features.size() == 0) continue;
    volumes.push_back(s->keypoint_box.volume());
    edges.push_back(s->keypoint_box.longestEdge());
  }
  const MeanStd volume = meanStd(volumes), edge = meanStd(edges);
  BoxStats box;
  box.mean_volume = static_cast<float>(volume.mean);
  box.std_volume = static_cast<float>(volume.std);
  box.mean_max_edge = static_cast<float>(edge.mean);
  box.std_max_edge = static_cast<float>(edge.std);
  box.min_volume = static_cast<float>(std::max(0.0, *std::min_element(volumes.begin(), volumes.end()) - volume.std));
  box.max_volume = static_cast<float>(*std::max_element(volumes.begin(), volumes.end()) + volume.std);
  box.max_edge = static_cast<float>(*std::max_element(edges.begin(), edges.end()) + edge.std);
  return box;
}

// A category without codebooks, votes or thresholds yet. Throws unless its scans come from at
// least 2 models and have keypoints: leave-one-out needs a model to hold out and others to vote.
CategoryModel categoryModel(const std::string& name, const CategoryScans& category, const TrainingParams& params) {
  size_t keypoints = 0;
  for (const auto* s : category.scans) keypoints += s->features.size();
  if (category.models < 2 || keypoints == 0) {
    throw Error(ErrorCode::kInvalidInput, "training: category '" + name + "' has " + std::to_string(category.models) +
                                              " models and " + std::to_string(keypoints) +
                                              " keypoints; leave-one-out thresholds need at least 2 models with keypoints");
  }
  CategoryModel model;
  model.name = name;
  const auto bin = params.bin_sizes.find(name);
  model.bin_size = bin != params.bin_sizes.end() ? bin->second : params.default_bin_size;
  model.training_models = category.models;
  model.training_scans = static_cast<int>(category.scans.size());
  model.box = keypointBoxStats(category.scans);
  // Scans made without a mesh (hand-made, or from another tool) carry no object size: such a
  // category has no size priors and its boxes come from the keypoints.
  const bool sized = std::all_of(category.scans.begin(), category.scans.end(),
                                 [](const TrainingScan* s) { return (s->object_size.array() > 0).all(); });
  if (sized) {
    model.objects.resize(static_cast<size_t>(category.models));
    for (const auto* s : category.scans) {
      TrainingObject& object = model.objects[static_cast<size_t>(s->model_index)];
      object.size = s->object_size;
      object.center_height = s->object_center.z();
      object.size_guessed = s->size_guessed;
    }
  }
  return model;
}

// Training meshes stand upright on z = 0, so a scan's up and floor are known exactly; the
// gravity stage's estimate of them is replaced.
void setKnownFloor(Features& features) {
  Gravity& g = *features.gravity;
  g.up = Eigen::Vector3f::UnitZ();
  g.source = UpSource::kGiven;
  g.floor_level = 0.0f;
  features.heights.resize(features.size());
  for (size_t k = 0; k < features.size(); ++k) features.heights[k] = features.positions[k].z();
}

// k-means of descriptors into a codebook, with its progress line.
Codebook codebookOf(const DescriptorMatrix& descriptors, const KMeansParams& params, const std::string& name,
                    const TrainingParams& training) {
  const auto start = Clock::now();
  const KMeansResult km = kmeans(descriptors, params);
  Codebook codebook(km.centers);
  if (training.progress) {
    training.progress(name + " codebook: k-means of " + std::to_string(descriptors.rows()) + " descriptors into " +
                      std::to_string(km.centers.rows()) + " codewords, " + std::to_string(km.iterations) +
                      " iterations, mean distance " + fixed(km.mean_distance, 3) + ", " +
                      fixed(secondsSince(start), 1) + " s");
  }
  return codebook;
}

// The codebook each category's votes go under: one over every category's scans, or one per
// category. Stored in `model`; the pointers point into it.
std::vector<const Codebook*> trainCodebooks(CodebookType type, const std::vector<TrainingScan>& scans,
                                            const std::vector<CategoryScans>& by_category, const TrainingParams& params,
                                            Model& model) {
  std::vector<const Codebook*> codebook_of(by_category.size());
  if (type == CodebookType::kGlobal) {
    DescriptorMatrix descriptors;
    if (params.balanced_global_codebook) {
      std::vector<DescriptorMatrix> groups;
      for (const auto& c : by_category) groups.push_back(stackDescriptors(c.scans));
      // A stream of the seed apart from the one k-means draws its starting centres from.
      descriptors = balancedRows(groups, params.global_kmeans.max_samples, params.global_kmeans.seed + 17u);
    } else {
      std::vector<const TrainingScan*> all;
      for (const auto& s : scans) all.push_back(&s);
      descriptors = stackDescriptors(all);
    }
    model.global_codebook = codebookOf(descriptors, params.global_kmeans,
                                       params.balanced_global_codebook ? "global (balanced)" : "global", params);
    std::fill(codebook_of.begin(), codebook_of.end(), &*model.global_codebook);
    return codebook_of;
  }
  for (size_t c = 0; c < by_category.size(); ++c) {
    CategoryModel& category = model.categories[c];
    category.own_codebook = codebookOf(stackDescriptors(by_category[c].scans), params.separated_kmeans, category.name, params);
    codebook_of[c] = &*category.own_codebook;
  }
  return codebook_of;
}

// The progress line of one category's thresholds under one codebook type.
std::string describeThresholds(const std::string& category, CodebookType type,
                               const std::vector<LeaveOneOutThreshold>& thresholds, float threshold_floor) {
  std::string line = category + " " + toString(type) + " thresholds:";
  bool floored_any = false, useless_any = false;
  for (const LeaveOneOutThreshold& t : thresholds) {
    line += std::string(" ") + toString(t.key.activation) + "/" + toString(t.key.weighting) + "=" + fixed(t.threshold, 3);
    if (t.floored) line += "(floored; mean " + fixed(t.mean, 3) + " - std " + fixed(t.std, 3) + ")";
    floored_any |= t.floored;
    if (!(t.threshold > 0)) line += "(!)";
    useless_any |= !(t.threshold > 0);
  }
  if (floored_any) {
    line += "  floored = mean - std fell below " + fixed(threshold_floor, 2) +
            " x the mean held-out score (few or dissimilar training models)";
  }
  if (useless_any) line += "  (!) = a threshold <= 0 admits every peak: pass a minimum score when detecting";
  return line;
}

// One codebook type: codebooks, each category's votes under them, and the leave-one-out
// thresholds, all stored in `model`.
void trainCodebookType(CodebookType type, const std::vector<TrainingScan>& scans,
                       const std::vector<CategoryScans>& by_category, const std::vector<const TrainingScan*>& background,
                       const TrainingParams& params, Model& model) {
  const auto report = [&](const std::string& line) {
    if (params.progress) params.progress(line);
  };
  const std::vector<const Codebook*> codebook_of = trainCodebooks(type, scans, by_category, params, model);

  const auto votes_start = Clock::now();
  std::vector<std::vector<TrainingVote>> votes(by_category.size());
  std::vector<int> background_counts;
  for (size_t c = 0; c < by_category.size(); ++c) {
    votes[c] = trainingVotes(by_category[c].scans, *codebook_of[c], params.voting.frame);
    VoteTable table = packVotes(votes[c], codebook_of[c]->size());
    if (!background.empty()) {
      if (background_counts.empty() || type == CodebookType::kSeparated) {
        background_counts = activationCounts(*codebook_of[c], background, model.trained_knn);
      }
      table.codeword_weights =
          codewordWeights(activationCounts(*codebook_of[c], by_category[c].scans, model.trained_knn), background_counts);
    }
    (type == CodebookType::kGlobal ? model.categories[c].global_votes : model.categories[c].own_votes) = std::move(table);
  }
  report(std::string(toString(type)) + " votes stored in " + fixed(secondsSince(votes_start), 1) + " s" +
         (background.empty() ? "" : ", codewords weighed against " + std::to_string(background.size()) + " background scans"));

  const auto loo_start = Clock::now();
  const std::vector<ActivationParams> activations{model.trained_knn, model.trained_cutoff};
  for (size_t c = 0; c < by_category.size(); ++c) {
    CategoryModel& category = model.categories[c];
    const VoteTable& table = type == CodebookType::kGlobal ? category.global_votes : category.own_votes;
    const LeaveOneOutInput input{category.name,          type,   *codebook_of[c], votes[c], by_category[c].scans,
                                 by_category[c].models, category.bin_size, params.voting, table.codeword_weights};
    const std::vector<LeaveOneOutThreshold> thresholds =
        leaveOneOutThresholds(input, activations, params.threshold_floor, threadCount(params));
    for (const LeaveOneOutThreshold& t : thresholds) {
      category.thresholds[t.key] = t.threshold;
      category.threshold_stats[t.key] = {static_cast<float>(t.mean), static_cast<float>(t.std)};
    }
    report(describeThresholds(category.name, type, thresholds, params.threshold_floor));
  }
  report(std::string(toString(type)) + " leave-one-out thresholds in " + fixed(secondsSince(loo_start), 1) + " s");
}

// A scan's features, the floor under them known, and the box of its keypoints.
void describeScan(const Scene& scene, const TrainingParams& params, TrainingScan& scan) {
  scan.features = extractFeatures(scene, params.front_end, false).features;
  if (scan.features.gravity) setKnownFloor(scan.features);
  scan.keypoint_box = fitOrientedBox(scan.features.positions);
}

}  // namespace

FrontEndParams defaultFrontEnd() {
  FrontEndParams params;
  params.downsample.leaf_size = kDefaultLeafSize;
  params.smoothing.radius = 2.0f * kDefaultLeafSize;
  params.normals.radius = 2.5f * kDefaultLeafSize;
  params.keypoints.radius = 2.5f * kDefaultLeafSize;
  params.shot.radius = 6.0f * kDefaultLeafSize;
  // Keypoints on the surfaces as well as their contours: a real chair seen by a Kinect gives about
  // half the contour keypoints of a rendered one (docs/EVALUATION.md measures it).
  params.keypoints.surface_spacing = 3.0f * kDefaultLeafSize;
  return params;
}

TrainingParams seedTrainingParams() {
  TrainingParams params;
  params.front_end = FrontEndParams{};  // the thesis's radii
  params.front_end.gravity.enabled = false;
  params.front_end.keypoints.unorganized = KeypointMethod::kBoundary;
  params.voting = VotingParams{VoteFrame::kLrf, 0.0f, false};
  params.render_floor = false;
  params.unsized_by_height = true;
  params.calibration.enabled = false;
  params.shape_spacing = 0;
  params.noise.projector_shadow = false;
  params.views.min_distance = 0;
  params.balanced_global_codebook = false;
  return params;
}

void reseed(TrainingParams& params, uint32_t seed) {
  // Distinct streams per use, each a function of the one seed.
  params.global_kmeans.seed = seed * 7919u + 1u;
  params.separated_kmeans.seed = seed * 7919u + 2u;
  params.noise.seed = seed * 7919u + 3u;
  params.calibration.seed = seed * 7919u + 4u;
}

float defaultBinSize(const std::string& category) {
  // The seed: ~10 cm bins for chairs, ~20 cm for tables and couches, i.e. by object size.
  try {
    return defaultCategorySize(category).maxCoeff() <= 1.0f ? 0.1f : 0.2f;
  } catch (const Error&) {
    return TrainingParams{}.default_bin_size;
  }
}

std::vector<Mesh> placeMeshes(const std::vector<TrainingMesh>& meshes, const TrainingParams& params) {
  const auto start = Clock::now();
  std::vector<Mesh> placed(meshes.size());
  parallelFor(static_cast<int>(meshes.size()), threadCount(params), [&](int i) {
    MeshPlacement placement = meshes[static_cast<size_t>(i)].placement;
    if (placement.uniform && params.unsized_by_height && placement.size.z() > 0) placement.size.head<2>().setZero();
    placed[static_cast<size_t>(i)] = placeMesh(loadMesh(meshes[static_cast<size_t>(i)].path), placement);
  });
  if (params.progress) params.progress("loaded " + std::to_string(meshes.size()) + " meshes in " + fixed(secondsSince(start), 1) + " s");
  return placed;
}

std::vector<int> modelIndices(const std::vector<TrainingMesh>& meshes) {
  std::vector<int> model_index(meshes.size());
  std::map<std::string, int> per_category;
  for (size_t i = 0; i < meshes.size(); ++i) model_index[i] = per_category[meshes[i].category]++;
  return model_index;
}

std::vector<TrainingScan> scanMeshes(const std::vector<TrainingMesh>& meshes, const TrainingParams& params) {
  return scanMeshes(meshes, placeMeshes(meshes, params), params);
}

std::vector<TrainingScan> scanMeshes(const std::vector<TrainingMesh>& meshes, const std::vector<Mesh>& placed,
                                     const TrainingParams& params, std::vector<Scene>* scenes) {
  if (placed.size() != meshes.size()) {
    throw Error(ErrorCode::kInternal, "scanMeshes: " + std::to_string(placed.size()) + " placed meshes for " +
                                          std::to_string(meshes.size()));
  }
  const auto start = Clock::now();
  const int threads = threadCount(params);
  const std::vector<int> model_index = modelIndices(meshes);
  std::map<std::string, int> per_category;
  for (const auto& m : meshes) ++per_category[m.category];

  std::vector<std::vector<Eigen::Isometry3f>> views(meshes.size());
  std::vector<std::pair<int, int>> jobs;  // (mesh, view)
  for (size_t m = 0; m < meshes.size(); ++m) {
    views[m] = viewRing(placed[m], params.views);
    for (size_t v = 0; v < views[m].size(); ++v) jobs.emplace_back(static_cast<int>(m), static_cast<int>(v));
  }
  const Mesh floor = floorMesh(params.floor_size);
  std::vector<TrainingScan> scans(jobs.size());
  if (scenes) scenes->assign(jobs.size(), Scene{});
  std::mutex progress_mutex;
  int done = 0;
  std::vector<Eigen::AlignedBox3f> bounds;
  for (const auto& p : placed) bounds.push_back(p.bounds());
  // Each view's points near its object, for the fused scans.
  std::vector<std::vector<Eigen::Vector3f>> view_points(params.fused.enabled ? jobs.size() : 0);
  parallelFor(static_cast<int>(jobs.size()), threads, [&](int j) {
    const auto scan_start = Clock::now();
    const auto [m, v] = jobs[static_cast<size_t>(j)];
    const TrainingMesh& mesh = meshes[static_cast<size_t>(m)];
    NoiseParams noise = params.noise;
    noise.seed += static_cast<uint32_t>(j);  // independent noise per scan, reproducible
    std::vector<const Mesh*> rendered{&placed[static_cast<size_t>(m)]};
    if (params.render_floor) rendered.push_back(&floor);
    const DepthImage depth = renderDepth(rendered, views[static_cast<size_t>(m)][static_cast<size_t>(v)], params.intrinsics, noise);
    const std::string source = mesh.path + " view " + std::to_string(v + 1);
    TrainingScan& scan = scans[static_cast<size_t>(j)];
    scan.category = mesh.category;
    scan.model_index = model_index[static_cast<size_t>(m)];
    scan.object_center = bounds[static_cast<size_t>(m)].center();
    scan.object_size = bounds[static_cast<size_t>(m)].sizes();
    scan.size_guessed = mesh.placement.size_guessed;
    Scene scene = depthImageToWorldScene(depth, source);
    scene.up = Eigen::Vector3f::UnitZ();  // meshes are placed upright on z = 0
    if (params.fused.enabled) {
      const Eigen::AlignedBox3f& b = bounds[static_cast<size_t>(m)];
      const float margin = params.fused.margin;
      auto& kept = view_points[static_cast<size_t>(j)];
      for (const auto& p : scene.cloud->points) {
        if (p.x >= b.min().x() - margin && p.x <= b.max().x() + margin && p.y >= b.min().y() - margin &&
            p.y <= b.max().y() + margin) {
          kept.push_back(p.getVector3fMap());
        }
      }
    }
    describeScan(scene, params, scan);
    if (scenes) (*scenes)[static_cast<size_t>(j)] = std::move(scene);
    if (params.progress) {
      std::lock_guard<std::mutex> lock(progress_mutex);
      params.progress("scanned " + std::to_string(++done) + "/" + std::to_string(jobs.size()) + " " + mesh.category +
                      " " + std::to_string(scan.model_index + 1) + "/" + std::to_string(per_category[mesh.category]) +
                      " view " + std::to_string(v + 1) + ": " + std::to_string(scan.features.size()) + " keypoints, " +
                      fixed(secondsSince(scan_start), 2) + " s");
    }
  });
  if (params.fused.enabled) {
    // Jobs are in mesh order, views[m].size() per mesh.
    std::vector<size_t> first(meshes.size() + 1, 0);
    for (size_t m = 0; m < meshes.size(); ++m) first[m + 1] = first[m] + views[m].size();
    std::vector<TrainingScan> fused(meshes.size());
    std::vector<Scene> fused_scenes(meshes.size());
    parallelFor(static_cast<int>(meshes.size()), threads, [&](int m) {
      const auto mi = static_cast<size_t>(m);
      std::vector<Eigen::Vector3f> all;
      for (size_t j = first[mi]; j < first[mi + 1]; ++j) {
        all.insert(all.end(), view_points[j].begin(), view_points[j].end());
        std::vector<Eigen::Vector3f>().swap(view_points[j]);
      }
      Eigen::Vector3f viewpoint = Eigen::Vector3f::Zero();
      if (!views[mi].empty()) viewpoint = views[mi].front().translation();
      Scene& scene = fused_scenes[mi];
      // Cropped to the object's footprint widened by the margin, averaged per cube as a TSDF
      // averages the views' noise.
      scene = fusedCloud(all, params.fused.spacing, viewpoint, meshes[mi].path + " fused");
      TrainingScan& scan = fused[mi];
      scan.category = meshes[mi].category;
      scan.model_index = model_index[mi];
      scan.object_center = bounds[mi].center();
      scan.object_size = bounds[mi].sizes();
      scan.size_guessed = meshes[mi].placement.size_guessed;
      describeScan(scene, params, scan);
    });
    for (auto& f : fused) scans.push_back(std::move(f));
    if (scenes) {
      for (auto& f : fused_scenes) scenes->push_back(std::move(f));
    }
  }
  if (params.progress) params.progress("scanning took " + fixed(secondsSince(start), 1) + " s");
  return scans;
}

Model trainFromScans(const std::vector<TrainingScan>& scans, const std::vector<std::string>& categories,
                     const TrainingParams& params, const std::vector<const TrainingScan*>& background) {
  checkTrainingParams(categories, params);
  Model model;
  model.front_end = params.front_end;
  model.voting = params.voting;
  model.trained_knn = params.knn;
  model.trained_knn.strategy = ActivationStrategy::kKnn;
  model.trained_cutoff = params.cutoff;
  model.trained_cutoff.strategy = ActivationStrategy::kCutoff;
  const std::vector<CategoryScans> by_category = scansByCategory(scans, categories);
  for (size_t c = 0; c < categories.size(); ++c) {
    model.categories.push_back(categoryModel(categories[c], by_category[c], params));
  }
  if (params.global_codebook) trainCodebookType(CodebookType::kGlobal, scans, by_category, background, params, model);
  if (params.separated_codebooks) {
    trainCodebookType(CodebookType::kSeparated, scans, by_category, background, params, model);
  }
  return model;
}

namespace {

// Each training object's points for verification, sampled from its placed mesh.
void keepShapes(const std::vector<TrainingMesh>& meshes, const std::vector<Mesh>& placed, const TrainingParams& params,
                Model& model) {
  const std::vector<int> model_index = modelIndices(meshes);
  for (size_t i = 0; i < meshes.size(); ++i) {
    auto category = std::find_if(model.categories.begin(), model.categories.end(),
                                 [&](const CategoryModel& c) { return c.name == meshes[i].category; });
    if (category == model.categories.end()) continue;
    const auto index = static_cast<size_t>(model_index[i]);
    if (index >= category->objects.size()) continue;  // a category without sizes has no objects
    category->objects[index].surface = sampleSurface(placed[i], params.shape_spacing,
                                                     static_cast<size_t>(std::max(0, params.shape_points)),
                                                     static_cast<uint32_t>(i + 1));
  }
}

}  // namespace

Model train(const std::vector<TrainingMesh>& meshes, const TrainingParams& params) {
  if (meshes.empty()) throw Error(ErrorCode::kInvalidInput, "training: no meshes");
  const auto start = Clock::now();
  std::vector<std::string> categories;
  for (const auto& m : meshes) {
    if (m.category != kBackgroundCategory &&
        std::find(categories.begin(), categories.end(), m.category) == categories.end()) {
      categories.push_back(m.category);
    }
  }
  if (categories.empty()) throw Error(ErrorCode::kInvalidInput, "training: only background meshes, no category");
  const std::vector<Mesh> placed = placeMeshes(meshes, params);
  std::vector<TrainingScan> scanned = scanMeshes(meshes, placed, params);
  std::vector<TrainingScan> scans, background_scans;
  for (auto& s : scanned) (s.category == kBackgroundCategory ? background_scans : scans).push_back(std::move(s));
  std::vector<const TrainingScan*> background;
  for (const auto& s : background_scans) background.push_back(&s);
  Model model = trainFromScans(scans, categories, params, background);
  if (params.shape_spacing > 0) keepShapes(meshes, placed, params, model);
  if (params.calibration.enabled && model.global_codebook) {
    const auto calibration_start = Clock::now();
    std::vector<PlacedObject> objects;
    const std::vector<int> model_index = modelIndices(meshes);
    for (size_t i = 0; i < meshes.size(); ++i) objects.push_back({meshes[i].category, model_index[i], &placed[i]});
    calibrate(model, scans, objects, params);
    if (params.progress) params.progress("calibration took " + fixed(secondsSince(calibration_start), 1) + " s");
  }
  for (const auto& m : meshes) model.provenance.meshes.push_back(m.category + "\t" + m.path + "\t" + m.credit);
  model.provenance.scans = static_cast<int>(scans.size());
  model.provenance.created = utcNow();
  model.provenance.code_version = codeVersion();
  model.provenance.command = params.command;
  if (params.progress) params.progress("training took " + fixed(secondsSince(start), 1) + " s");
  return model;
}

}  // namespace ism
