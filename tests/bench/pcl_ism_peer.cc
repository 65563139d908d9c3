// pcl-ism-peer: PCL's own Implicit Shape Model (pcl::ism::ImplicitShapeModelEstimation, FPFH
// 33-d features) side by side with ours, on the same training scans and the same scenes, scored
// by the same rule as `ism-eval real`.
//
// Same training scans: the meshes of the manifest our model was trained from, rendered by
// core's virtual scanner with the views and per-scan noise seeds that scanMeshes() uses. Same
// scenes: annotated clouds (a folder of *.json, a .json, or a cloud with its .json beside it).
// Same rule: ism::ClassScorer (the seed's centre-distance match, r = TP / (objects + FP)) with
// our model's category names and box sizes; a PCL peak's position is its vote centre (PCL
// keeps no supporting keypoints), ours is the centroid of the supporting keypoints, as ism-eval
// scores it.
//
// PCL's ISM has no detection threshold: findStrongestPeaks() returns every non-maximum-
// suppressed density peak. Two readings are scored: every peak, and the strongest peak per
// category and scene.
#include <pcl/features/fpfh_omp.h>
#include <pcl/features/impl/fpfh.hpp>
#include <pcl/features/impl/fpfh_omp.hpp>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/recognition/implicit_shape_model.h>
#include <pcl/recognition/impl/implicit_shape_model.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/common/error.h"
#include "core/eval/eval.h"
#include "core/io/cloud_io.h"
#include "core/model/model_file.h"
#include "core/recognition/recognizer.h"
#include "core/scanner/scanner.h"
#include "core/training/trainer.h"

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;
constexpr int kFeatureSize = 33;  // FPFH: 3 x 11 bins
using PclIsm = pcl::ism::ImplicitShapeModelEstimation<kFeatureSize, pcl::PointXYZ, pcl::Normal>;
using Fpfh = pcl::FPFHEstimationOMP<pcl::PointXYZ, pcl::Normal, pcl::Histogram<kFeatureSize>>;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

int threads() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : (v[n / 2 - 1] + v[n / 2]) / 2;
}

struct Params {
  std::string manifest;
  std::string model_path;
  std::vector<std::string> scenes;
  std::string json_path;
  int views = 12;           // as ism-train (TrainingParams::views)
  // The PCL side. Points first go through the same kind of front end as ours: a 1 cm voxel grid
  // and PCA normals over 3 cm, oriented to the sensor (tutorial: NormalEstimation). Then ISM's
  // own keypoints (voxel-grid sampling at `sampling`), FPFH over `fpfh_radius` among those
  // keypoints (ISM hands FPFH the sampled cloud as its search surface), k-means with PCL's
  // default 184 clusters, per class sigma = 10% of the object radius (PCL's own calculateSigmas()
  // rule: the mean over the class's training clouds of their largest distance from the centroid,
  // / 10), and the tutorial's peak search: findStrongestPeaks(radius = 10 sigma, sigma).
  float leaf = 0.01f;
  float normal_radius = 0.03f;
  float sampling = 0.05f;
  float fpfh_radius = 0.15f;
  int clusters = 184;
  float sigma_fraction = 0.1f;
  int ours_repeats = 3;     // our recognize() per scene; the median is reported
  // PCL's ISM expresses votes in a frame built from the normal and the global axes
  // (alignYCoordWithNormal), so it only recognises objects upright in the frame it was trained
  // in (z up). Scenes whose ground truth gives the floor's normal are rotated to z up for it;
  // ours needs no such help (its LRFs are rotation invariant) and gets the scene as it is.
  bool align_up = true;
  std::string save_pcl_model, load_pcl_model;  // PCL's text format (ISMModel::saveModelToFile)
};

int usage() {
  std::cerr << "usage: pcl-ism-peer --manifest TRAIN.tsv --model OURS.ismm [options] SCENE...\n"
               "  SCENE: a folder of annotated scenes (*.json), a scene .json, or a cloud with its .json\n"
               "  --views N           virtual scans per mesh (default 12, as ism-train)\n"
               "  --sampling M        PCL ISM keypoint voxel (m, default 0.05)\n"
               "  --fpfh-radius M     FPFH support radius (m, default 0.15)\n"
               "  --normal-radius M   normal radius (m, default 0.03)\n"
               "  --leaf M            voxel grid before normals (m, default 0.01)\n"
               "  --clusters K        k-means clusters (default 184, PCL's default)\n"
               "  --sigma-fraction F  sigma as a fraction of the class's object radius (default 0.1)\n"
               "  --ours-repeats N    runs of our recognize() per scene (default 3, median kept)\n"
               "  --align-up on|off   rotate scenes with a \"floor_normal\" to z up for PCL (default on)\n"
               "  --threads N         OpenMP threads for both (default: all)\n"
               "  --save-pcl-model F  write PCL's trained model; --load-pcl-model F: use it, no training\n"
               "  --json FILE         write the results as JSON\n";
  return 2;
}

// Points with a normal PCL's ISM can use: finite, and not perpendicular to y in either of the
// planes alignYCoordWithNormal() divides by (it would divide by zero and cast NaN votes).
bool usableNormal(const pcl::Normal& n) {
  if (!std::isfinite(n.normal_x) || !std::isfinite(n.normal_y) || !std::isfinite(n.normal_z)) return false;
  return std::hypot(n.normal_y, n.normal_z) > 1e-6f && std::hypot(n.normal_x, n.normal_y) > 1e-6f;
}

struct Prepared {
  pcl::PointCloud<pcl::PointXYZ>::Ptr points{new pcl::PointCloud<pcl::PointXYZ>};
  pcl::PointCloud<pcl::Normal>::Ptr normals{new pcl::PointCloud<pcl::Normal>};
  size_t dropped = 0;  // points without a usable normal
};

// `rotation` applied to the points, then a voxel grid, then normals towards `viewpoint` (also
// rotated); points whose normal is unusable are dropped.
Prepared prepare(const ism::Cloud& cloud, const Eigen::Vector3f& viewpoint, const Params& p,
                 const Eigen::Quaternionf& rotation = Eigen::Quaternionf::Identity()) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr xyz(new pcl::PointCloud<pcl::PointXYZ>);
  xyz->reserve(cloud.size());
  const Eigen::Matrix3f r = rotation.toRotationMatrix();
  for (const auto& q : cloud) {
    pcl::PointXYZ point;
    point.getVector3fMap() = r * q.getVector3fMap();
    xyz->push_back(point);
  }
  const Eigen::Vector3f sensor = r * viewpoint;
  pcl::PointCloud<pcl::PointXYZ>::Ptr grid(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::VoxelGrid<pcl::PointXYZ> voxels;
  voxels.setLeafSize(p.leaf, p.leaf, p.leaf);
  voxels.setInputCloud(xyz);
  voxels.filter(*grid);
  pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> estimator;
  estimator.setNumberOfThreads(static_cast<unsigned>(threads()));
  estimator.setRadiusSearch(p.normal_radius);
  estimator.setViewPoint(sensor.x(), sensor.y(), sensor.z());
  estimator.setInputCloud(grid);
  pcl::PointCloud<pcl::Normal> normals;
  estimator.compute(normals);
  Prepared out;
  for (size_t i = 0; i < grid->size(); ++i) {
    if (!usableNormal(normals[i])) {
      ++out.dropped;
      continue;
    }
    out.points->push_back((*grid)[i]);
    out.normals->push_back(normals[i]);
  }
  return out;
}

// The "floor_normal" (up, in the cloud's frame) of a scene's ground truth, when it has one.
std::optional<Eigen::Vector3f> floorNormal(const std::string& json_path) {
  std::ifstream in(json_path);
  const json doc = json::parse(in, nullptr, false);
  if (doc.is_discarded() || !doc.contains("floor_normal")) return std::nullopt;
  const json& n = doc["floor_normal"];
  if (!n.is_array() || n.size() != 3 || !n[0].is_number() || !n[1].is_number() || !n[2].is_number()) {
    throw ism::Error(ism::ErrorCode::kInvalidInput, json_path + ": \"floor_normal\" must be an array of 3 numbers");
  }
  const Eigen::Vector3f up(n[0].get<float>(), n[1].get<float>(), n[2].get<float>());
  if (!(up.norm() > 0)) throw ism::Error(ism::ErrorCode::kInvalidInput, json_path + ": \"floor_normal\" is zero");
  return up.normalized();
}

// ---------------------------------------------------------------------------------------------
// Training scans: what ism::scanMeshes() renders, as clouds instead of features.

struct TrainingSet {
  std::vector<std::string> categories;  // class id = index
  std::vector<pcl::PointCloud<pcl::PointXYZ>::Ptr> clouds;
  std::vector<pcl::PointCloud<pcl::Normal>::Ptr> normals;
  std::vector<unsigned> classes;
  std::vector<float> sigmas;  // per class
  size_t points = 0;
  double scan_ms = 0;
};

// Largest distance of a point from the centroid. PCL's calculateSigmas() takes the square root
// of the largest p_i . p_j over pairs of the centred cloud, which approaches this from below; it
// is quadratic in the points (hours on 252 scans), this is linear.
float cloudRadius(const pcl::PointCloud<pcl::PointXYZ>& cloud) {
  if (cloud.empty()) return 0;
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
  for (const auto& q : cloud) centroid += q.getVector3fMap();
  centroid /= static_cast<float>(cloud.size());
  float radius = 0;
  for (const auto& q : cloud) radius = std::max(radius, (q.getVector3fMap() - centroid).norm());
  return radius;
}

// In order of first appearance: PCL's class ids.
std::vector<std::string> categoriesOf(const std::vector<ism::TrainingMesh>& meshes) {
  std::vector<std::string> categories;
  for (const auto& m : meshes) {
    if (std::find(categories.begin(), categories.end(), m.category) == categories.end()) categories.push_back(m.category);
  }
  return categories;
}

TrainingSet renderTrainingScans(const std::vector<ism::TrainingMesh>& meshes, const Params& p) {
  const auto start = Clock::now();
  TrainingSet set;
  set.categories = categoriesOf(meshes);
  ism::TrainingParams params;  // the scanner settings ism-train uses
  params.views.views = p.views;
  const std::vector<ism::Mesh> placed = ism::placeMeshes(meshes, params);
  std::vector<std::vector<Eigen::Isometry3f>> views(meshes.size());
  std::vector<std::pair<size_t, size_t>> jobs;  // (mesh, view), in scanMeshes()'s order: it seeds the noise
  for (size_t m = 0; m < meshes.size(); ++m) {
    views[m] = ism::viewRing(placed[m], params.views);
    for (size_t v = 0; v < views[m].size(); ++v) jobs.emplace_back(m, v);
  }
  std::vector<Prepared> scans(jobs.size());
  std::vector<float> radii(jobs.size());
  std::string failure;
#pragma omp parallel for schedule(dynamic)
  for (size_t j = 0; j < jobs.size(); ++j) {
    try {
      const auto [m, v] = jobs[j];
      ism::NoiseParams noise = params.noise;
      noise.seed += static_cast<uint32_t>(j);
      const ism::DepthImage depth = ism::renderDepth({&placed[m]}, views[m][v], params.intrinsics, noise);
      const ism::Scene scene = ism::depthImageToWorldScene(depth, meshes[m].path + " view " + std::to_string(v + 1));
      scans[j] = prepare(*scene.cloud, scene.sensor_origin, p);
      radii[j] = cloudRadius(*scans[j].points);
    } catch (const std::exception& e) {
#pragma omp critical
      failure = e.what();
    }
  }
  if (!failure.empty()) throw ism::Error(ism::ErrorCode::kInvalidInput, "scanning: " + failure);
  std::vector<std::vector<float>> class_radii(set.categories.size());
  for (size_t j = 0; j < jobs.size(); ++j) {
    if (scans[j].points->empty()) continue;  // a view that saw nothing
    const auto c = static_cast<unsigned>(
        std::find(set.categories.begin(), set.categories.end(), meshes[jobs[j].first].category) - set.categories.begin());
    set.points += scans[j].points->size();
    set.clouds.push_back(scans[j].points);
    set.normals.push_back(scans[j].normals);
    set.classes.push_back(c);
    class_radii[c].push_back(radii[j]);
  }
  for (const auto& s : class_radii) {
    float mean = 0;
    for (float v : s) mean += v;
    set.sigmas.push_back(s.empty() ? 0.1f : p.sigma_fraction * mean / static_cast<float>(s.size()));
  }
  set.scan_ms = msSince(start);
  return set;
}

// The model category names the scenes' ground truth may use. Real frames are labelled with
// coarse classes (chair, table, sofa: the default mapping), the shipped sample scene with the
// model's own names; model categories sharing a coarse class also share the names, so that they
// stay one class (as `ism-eval real --map office_chair='chair|office_chair|dining_chair' ...`).
ism::CategoryMapping scoringMapping(const ism::Model& model) {
  const ism::CategoryMapping coarse = ism::defaultCategoryMapping();
  ism::CategoryMapping mapping;
  for (const auto& c : model.categories) {
    const auto it = coarse.find(c.name);
    std::vector<std::string> targets = it == coarse.end() ? std::vector<std::string>{} : it->second;
    for (const auto& other : model.categories) {
      const auto o = coarse.find(other.name);
      const bool same_class = other.name == c.name || (it != coarse.end() && o != coarse.end() && o->second == it->second);
      if (same_class) targets.push_back(other.name);
    }
    mapping[c.name] = targets;
  }
  return mapping;
}

json scoresJson(const ism::ClassScorer& scorer) {
  json classes = json::array();
  int objects = 0, tp = 0, fp = 0;
  for (const auto& s : scorer.scores()) {
    const auto number = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
    classes.push_back({{"class", s.name}, {"objects", s.objects}, {"tp", s.tp}, {"fp", s.fp}, {"fn", s.fn},
                       {"rate", number(s.rate)}, {"ap", number(s.ap)}});
    objects += s.objects;
    tp += s.tp;
    fp += s.fp;
  }
  const double rate = objects + fp > 0 ? static_cast<double>(tp) / (objects + fp) : 0.0;
  return {{"classes", classes}, {"objects", objects}, {"tp", tp}, {"fp", fp}, {"fn", objects - tp}, {"rate", rate}};
}

std::string rateLine(const json& s) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(1) << 100.0 * s["rate"].get<double>() << "% (TP " << s["tp"] << ", FP "
      << s["fp"] << ", FN " << s["fn"] << ", objects " << s["objects"] << ")";
  return out.str();
}

}  // namespace

int main(int argc, char** argv) {
  Params p;
  int thread_count = 0;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string arg = argv[i];
      if (arg == "-h" || arg == "--help") return usage();
      if (arg.rfind("--", 0) != 0) {
        p.scenes.push_back(arg);
        continue;
      }
      if (i + 1 >= argc) {
        std::cerr << "pcl-ism-peer: " << arg << " needs a value\n";
        return usage();
      }
      const std::string v = argv[++i];
      const auto positive = [&](float x) {
        if (!(x > 0) || !std::isfinite(x)) throw std::invalid_argument(arg + " '" + v + "' must be positive");
        return x;
      };
      if (arg == "--manifest") p.manifest = v;
      else if (arg == "--model") p.model_path = v;
      else if (arg == "--json") p.json_path = v;
      else if (arg == "--views") p.views = static_cast<int>(positive(std::stof(v)));
      else if (arg == "--sampling") p.sampling = positive(std::stof(v));
      else if (arg == "--fpfh-radius") p.fpfh_radius = positive(std::stof(v));
      else if (arg == "--normal-radius") p.normal_radius = positive(std::stof(v));
      else if (arg == "--leaf") p.leaf = positive(std::stof(v));
      else if (arg == "--clusters") p.clusters = static_cast<int>(positive(std::stof(v)));
      else if (arg == "--sigma-fraction") p.sigma_fraction = positive(std::stof(v));
      else if (arg == "--ours-repeats") p.ours_repeats = static_cast<int>(positive(std::stof(v)));
      else if (arg == "--threads") thread_count = static_cast<int>(positive(std::stof(v)));
      else if (arg == "--save-pcl-model") p.save_pcl_model = v;
      else if (arg == "--load-pcl-model") p.load_pcl_model = v;
      else if (arg == "--align-up") {
        if (v != "on" && v != "off") throw std::invalid_argument("--align-up '" + v + "' must be on or off");
        p.align_up = v == "on";
      }
      else {
        std::cerr << "pcl-ism-peer: unknown option " << arg << '\n';
        return usage();
      }
    }
  } catch (const std::exception& e) {
    std::cerr << "pcl-ism-peer: " << e.what() << '\n';
    return 2;
  }
  if (p.manifest.empty() || p.model_path.empty() || p.scenes.empty()) {
    std::cerr << "pcl-ism-peer: --manifest, --model and at least one scene are required\n";
    return usage();
  }
#ifdef _OPENMP
  if (thread_count > 0) omp_set_num_threads(thread_count);
#endif

  json out;
  try {
    const ism::Model model = ism::loadModel(p.model_path);
    const auto meshes = ism::readManifest(p.manifest);
    for (const auto& m : meshes) {
      if (model.find(m.category) == nullptr) {
        throw ism::Error(ism::ErrorCode::kInvalidInput, "manifest category '" + m.category + "' is not in the model " +
                                                            p.model_path + " (its box sizes are needed for scoring)");
      }
    }
    std::vector<ism::AnnotatedScene> scenes;
    for (const auto& path : ism::findSceneAnnotations(p.scenes)) scenes.push_back(ism::readSceneAnnotation(path));
    std::cout << "pcl-ism-peer: " << meshes.size() << " meshes x " << p.views << " views, " << scenes.size()
              << " scenes, " << threads() << " threads" << std::endl;

    // Training.
    Fpfh::Ptr fpfh(new Fpfh);
    fpfh->setRadiusSearch(p.fpfh_radius);
    fpfh->setNumberOfThreads(static_cast<unsigned>(threads()));
    PclIsm ism_estimator;
    ism_estimator.setFeatureEstimator(fpfh);
    ism_estimator.setSamplingSize(p.sampling);
    ism_estimator.setNumberOfClusters(static_cast<unsigned>(p.clusters));
    PclIsm::ISMModelPtr pcl_model(new pcl::features::ISMModel);
    TrainingSet set;
    double train_ms = 0;
    if (!p.load_pcl_model.empty()) {  // parameter studies: the same trained model on other scenes
      set.categories = categoriesOf(meshes);
      std::string path = p.load_pcl_model;
      if (!pcl_model->loadModelFromfile(path) || pcl_model->number_of_classes_ != set.categories.size() ||
          pcl_model->number_of_clusters_ != static_cast<unsigned>(p.clusters)) {
        throw ism::Error(ism::ErrorCode::kInvalidInput, "PCL ISM model " + path + " cannot be read or does not match "
                                                        "the manifest's categories and --clusters");
      }
      set.sigmas = pcl_model->sigmas_;
      std::cout << "loaded PCL ISM model " << path << std::endl;
    } else {
      set = renderTrainingScans(meshes, p);
      std::cout << "rendered " << set.clouds.size() << " training scans (" << set.points << " points after the "
                << p.leaf << " m grid) in " << std::fixed << std::setprecision(1) << set.scan_ms / 1000 << " s"
                << std::endl;
      if (set.clouds.empty()) throw ism::Error(ism::ErrorCode::kInvalidInput, "no training scan saw any point");
      ism_estimator.setTrainingClouds(set.clouds);
      ism_estimator.setTrainingNormals(set.normals);
      ism_estimator.setTrainingClasses(set.classes);
      // Set explicitly: PCL's own estimate (calculateSigmas) is quadratic in each cloud's points.
      ism_estimator.setSigmaDists(set.sigmas);
      const auto train_start = Clock::now();
      if (!ism_estimator.trainISM(pcl_model)) throw ism::Error(ism::ErrorCode::kInternal, "PCL trainISM returned false");
      train_ms = msSince(train_start);
      set.clouds.clear();  // memory for recognition
      set.normals.clear();
      if (!p.save_pcl_model.empty()) {
        std::string path = p.save_pcl_model;
        if (!pcl_model->saveModelToFile(path)) throw ism::Error(ism::ErrorCode::kIo, "cannot write " + path);
      }
    }
    const bool finite_model = pcl_model->clusters_centers_.allFinite();
    std::cout << "PCL ISM model";
    if (p.load_pcl_model.empty()) std::cout << " trained in " << std::fixed << std::setprecision(1) << train_ms / 1000 << " s";
    std::cout << ": " << pcl_model->number_of_visual_words_ << " words, " << pcl_model->number_of_clusters_ << " clusters"
              << (finite_model ? "" : " (WARNING: non-finite cluster centres)") << std::endl;
    if (pcl_model->number_of_visual_words_ == 0) {
      throw ism::Error(ism::ErrorCode::kInvalidInput, "PCL ISM found no describable keypoint in the training scans");
    }
    Clock::time_point start;

    out["params"] = {{"manifest", p.manifest}, {"model", p.model_path}, {"views", p.views}, {"threads", threads()},
                     {"leaf_m", p.leaf}, {"normal_radius_m", p.normal_radius}, {"sampling_m", p.sampling},
                     {"fpfh_radius_m", p.fpfh_radius}, {"clusters", p.clusters},
                     {"sigma_fraction", p.sigma_fraction}, {"ours_repeats", p.ours_repeats}, {"align_up", p.align_up},
                     {"ours_strategy", ism::strategyName({ism::CodebookType::kGlobal, model.trained_knn,
                                                          ism::VoteWeighting::kLocalization})}};
    json sigmas = json::object();
    for (size_t c = 0; c < set.categories.size(); ++c) sigmas[set.categories[c]] = set.sigmas[c];
    out["training"] = {{"scans", set.classes.size()}, {"points", set.points}, {"scan_s", set.scan_ms / 1000},
                       {"train_s", train_ms / 1000}, {"words", pcl_model->number_of_visual_words_},
                       {"finite_cluster_centres", finite_model}, {"sigmas_m", sigmas},
                       {"loaded_from", p.load_pcl_model}};

    // Recognition, scene by scene.
    const ism::CategoryMapping mapping = scoringMapping(model);
    ism::ClassScorer ours_scorer(model, mapping), pcl_all_scorer(model, mapping), pcl_top_scorer(model, mapping);
    ism::RecognitionOptions options;  // the service's defaults
    options.strategy.activation = model.trained_knn;
    std::vector<double> ours_times, pcl_times;
    json scene_rows = json::array();
    int pcl_failures = 0;
    for (const auto& annotation : scenes) {
      ism::Scene scene = ism::loadCloudFile(annotation.cloud_path);
      const Eigen::Vector3f viewpoint = ism::sceneViewpoint(annotation, scene, ism::ViewpointPolicy::kAuto);
      scene.sensor_origin = viewpoint;
      json row = {{"scene", annotation.name}, {"points", scene.cloud->size()}, {"objects", annotation.objects.size()}};

      std::vector<double> runs;
      ism::RecognitionResult ours;
      for (int r = 0; r < p.ours_repeats; ++r) {
        start = Clock::now();
        ours = ism::recognize(model, scene, options);
        runs.push_back(msSince(start));
      }
      const double ours_ms = median(runs);
      ours_times.push_back(ours_ms);
      const auto ours_counts = ours_scorer.addScene(annotation.objects, ours.hypotheses);
      row["ours"] = {{"ms", ours_ms}, {"keypoints", ours.keypoints}, {"hypotheses", ours.hypotheses.size()},
                     {"tp", ours_counts[0]}, {"fp", ours_counts[1]}, {"fn", ours_counts[2]}};

      // PCL: from the loaded cloud to peaks, every category.
      json pcl_row;
      std::vector<ism::Hypothesis> all_peaks, top_peaks;
      try {
        const std::optional<Eigen::Vector3f> up = p.align_up ? floorNormal(annotation.json_path) : std::nullopt;
        const Eigen::Quaternionf to_up =
            up ? Eigen::Quaternionf::FromTwoVectors(*up, Eigen::Vector3f::UnitZ()) : Eigen::Quaternionf::Identity();
        start = Clock::now();
        const Prepared prepared = prepare(*scene.cloud, viewpoint, p, to_up);
        const double prepare_ms = msSince(start);
        json per_class = json::object();
        size_t invalid = 0;
        for (size_t c = 0; c < set.categories.size(); ++c) {
          auto votes = ism_estimator.findObjects(pcl_model, prepared.points, prepared.normals, static_cast<int>(c));
          std::vector<pcl::ISMPeak, Eigen::aligned_allocator<pcl::ISMPeak>> peaks;
          const unsigned vote_count = votes->getNumberOfVotes();
          // findStrongestPeaks() indexes its votes unconditionally; an empty list has no peaks.
          if (vote_count > 0) {
            const double sigma = pcl_model->sigmas_[c];
            votes->findStrongestPeaks(peaks, static_cast<int>(c), 10.0 * sigma, sigma);
          }
          size_t kept = 0;
          json peak_list = json::array();
          for (const auto& peak : peaks) {
            if (!std::isfinite(peak.x) || !std::isfinite(peak.y) || !std::isfinite(peak.z) ||
                !std::isfinite(peak.density)) {
              ++invalid;
              continue;
            }
            ism::Hypothesis h;
            h.category = set.categories[c];
            h.score = static_cast<float>(peak.density);
            h.center = h.support_centroid = to_up.conjugate() * Eigen::Vector3f(peak.x, peak.y, peak.z);
            all_peaks.push_back(h);
            peak_list.push_back({h.center.x(), h.center.y(), h.center.z(), peak.density});
            if (kept++ == 0) top_peaks.push_back(h);  // findStrongestPeaks() returns the strongest first
          }
          per_class[set.categories[c]] = {{"votes", vote_count}, {"peaks", peak_list}};
        }
        const double pcl_ms = msSince(start);
        pcl_times.push_back(pcl_ms);
        pcl_row = {{"ms", pcl_ms}, {"prepare_ms", prepare_ms}, {"points", prepared.points->size()}, {"up_aligned", up.has_value()},
                   {"dropped_normals", prepared.dropped}, {"classes", per_class}, {"invalid_peaks", invalid}};
        if (all_peaks.empty()) pcl_row["note"] = "no peaks in any category";
      } catch (const std::exception& e) {
        ++pcl_failures;
        pcl_row = {{"error", e.what()}};
        all_peaks.clear();
        top_peaks.clear();
      }
      const auto all_counts = pcl_all_scorer.addScene(annotation.objects, all_peaks);
      const auto top_counts = pcl_top_scorer.addScene(annotation.objects, top_peaks);
      pcl_row["all_peaks"] = {{"tp", all_counts[0]}, {"fp", all_counts[1]}, {"fn", all_counts[2]}};
      pcl_row["top_peak"] = {{"tp", top_counts[0]}, {"fp", top_counts[1]}, {"fn", top_counts[2]}};
      row["pcl"] = pcl_row;
      std::cout << "scene " << annotation.name << ": ours " << std::setprecision(0) << ours_ms << " ms (TP/FP/FN "
                << ours_counts[0] << "/" << ours_counts[1] << "/" << ours_counts[2] << "), PCL ISM ";
      if (pcl_row.contains("error")) {
        std::cout << "FAILED: " << pcl_row["error"].get<std::string>();
      } else {
        std::cout << pcl_row["ms"].get<double>() << " ms (all peaks " << all_counts[0] << "/" << all_counts[1] << "/"
                  << all_counts[2] << ", top peak " << top_counts[0] << "/" << top_counts[1] << "/" << top_counts[2]
                  << ")";
      }
      std::cout << std::setprecision(1) << std::endl;
      scene_rows.push_back(row);
    }
    out["scenes"] = scene_rows;
    const double ours_median = median(ours_times), pcl_median = median(pcl_times);
    out["summary"] = {{"ours_median_ms", ours_median},
                      {"pcl_median_ms", std::isfinite(pcl_median) ? json(pcl_median) : json(nullptr)},
                      {"pcl_failures", pcl_failures},
                      {"ours", scoresJson(ours_scorer)},
                      {"pcl_all_peaks", scoresJson(pcl_all_scorer)},
                      {"pcl_top_peak", scoresJson(pcl_top_scorer)}};
    const json& s = out["summary"];
    std::cout << std::setprecision(1) << "median time per scene: ours " << ours_median << " ms, PCL ISM "
              << pcl_median << " ms";
    if (std::isfinite(pcl_median) && ours_median > 0) std::cout << " (PCL / ours = " << pcl_median / ours_median << ")";
    std::cout << "\nrecognition rate r = TP / (objects + FP): ours " << rateLine(s["ours"]) << "; PCL ISM every peak "
              << rateLine(s["pcl_all_peaks"]) << "; PCL ISM strongest peak per category "
              << rateLine(s["pcl_top_peak"]) << std::endl;
    if (pcl_failures > 0) std::cout << "PCL ISM failed on " << pcl_failures << " scene(s); see the JSON" << std::endl;
  } catch (const std::exception& e) {
    std::cerr << "pcl-ism-peer: " << e.what() << '\n';
    return 1;
  }
  if (!p.json_path.empty()) {
    std::ofstream file(p.json_path);
    file << out.dump(1) << '\n';
    if (!file) {
      std::cerr << "pcl-ism-peer: cannot write " << p.json_path << '\n';
      return 1;
    }
  }
  return 0;
}
