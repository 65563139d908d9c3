#include "core/training/trainer.h"

#include "core/common/version.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <ctime>
#include <exception>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <sstream>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/common/error.h"
#include "core/frontend/frontend.h"
#include "core/recognition/box_selection.h"
#include "core/recognition/voting.h"

namespace ism {
namespace {

namespace fs = std::filesystem;
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

int threadCount(const TrainingParams& params) {
#ifdef _OPENMP
  return params.threads > 0 ? params.threads : omp_get_max_threads();
#else
  (void)params;
  return 1;
#endif
}

// Runs body(i) for i in [0, n) on `threads` OpenMP threads; the first exception is rethrown.
template <typename F>
void parallelFor(int n, int threads, F&& body) {
  std::exception_ptr failure;
  std::mutex mutex;
#pragma omp parallel for schedule(dynamic) num_threads(threads)
  for (int i = 0; i < n; ++i) {
    try {
      body(i);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex);
      if (!failure) failure = std::current_exception();
    }
  }
  if (failure) std::rethrow_exception(failure);
}

struct MeanStd {
  double mean = 0, std = 0;
};

MeanStd meanStd(const std::vector<double>& values) {
  MeanStd r;
  if (values.empty()) return r;
  for (double v : values) r.mean += v;
  r.mean /= static_cast<double>(values.size());
  for (double v : values) r.std += (v - r.mean) * (v - r.mean);
  r.std = std::sqrt(r.std / static_cast<double>(values.size()));
  return r;
}

// A training vote before it is packed into a VoteTable: which model cast it is kept so that
// leave-one-out can drop a model's votes.
struct RawVote {
  int codeword;
  int model;
  Eigen::Vector3f vector;
};

// CSR table of the votes, optionally without those of model `excluded`.
VoteTable packVotes(const std::vector<RawVote>& raw, int codebook_size, int excluded = -1) {
  VoteTable table;
  table.offsets.assign(static_cast<size_t>(codebook_size) + 1, 0);
  for (const auto& v : raw) {
    if (v.model != excluded) ++table.offsets[static_cast<size_t>(v.codeword) + 1];
  }
  for (int c = 0; c < codebook_size; ++c) table.offsets[static_cast<size_t>(c) + 1] += table.offsets[static_cast<size_t>(c)];
  table.vectors.resize(table.offsets.back());
  std::vector<uint32_t> cursor(table.offsets.begin(), table.offsets.end() - 1);
  for (const auto& v : raw) {
    if (v.model != excluded) table.vectors[cursor[static_cast<size_t>(v.codeword)]++] = v.vector;
  }
  return table;
}

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

std::vector<std::string> splitTabs(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream s(line);
  std::string field;
  while (std::getline(s, field, '\t')) fields.push_back(field);
  if (!line.empty() && line.back() == '\t') fields.emplace_back();
  return fields;
}

}  // namespace

Eigen::Vector3f defaultCategorySize(const std::string& category) {
  // Typical catalogue dimensions (width, depth, height in m).
  static const std::map<std::string, Eigen::Vector3f> sizes = {
      {"office_chair", {0.65f, 0.65f, 1.0f}}, {"dining_chair", {0.45f, 0.5f, 0.9f}},
      {"dining_table", {1.4f, 0.9f, 0.75f}},  {"couch", {2.0f, 0.9f, 0.85f}},
      {"armchair", {0.85f, 0.85f, 0.85f}},     {"stool", {0.4f, 0.4f, 0.65f}},
      {"desk", {1.2f, 0.6f, 0.75f}},           {"bed", {1.6f, 2.0f, 0.55f}}};
  const auto it = sizes.find(category);
  if (it == sizes.end()) {
    std::string known;
    for (const auto& [name, size] : sizes) known += (known.empty() ? "" : ", ") + name;
    throw Error(ErrorCode::kInvalidInput, "no typical size known for category '" + category + "' (known: " + known +
                                              "); give the sizes in a manifest");
  }
  return it->second;
}

float defaultBinSize(const std::string& category) {
  // The seed: ~10 cm bins for chairs, ~20 cm for tables and couches, i.e. by object size.
  try {
    return defaultCategorySize(category).maxCoeff() <= 1.0f ? 0.1f : 0.2f;
  } catch (const Error&) {
    return TrainingParams{}.default_bin_size;
  }
}

std::vector<TrainingMesh> readManifest(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(ErrorCode::kNotFound, "manifest " + path + " does not exist or cannot be opened");
  const fs::path base = fs::path(path).parent_path();
  std::string line;
  if (!std::getline(in, line)) throw Error(ErrorCode::kInvalidInput, "manifest " + path + " is empty");
  std::map<std::string, size_t> column;
  const auto header = splitTabs(line);
  for (size_t i = 0; i < header.size(); ++i) column[header[i]] = i;
  for (const char* required : {"category", "path"}) {
    if (!column.count(required)) {
      throw Error(ErrorCode::kInvalidInput, "manifest " + path + ": the header has no '" + required + "' column");
    }
  }
  std::vector<TrainingMesh> meshes;
  for (int line_number = 2; std::getline(in, line); ++line_number) {
    if (line.empty() || line[0] == '#') continue;
    const auto fields = splitTabs(line);
    const std::string where = "manifest " + path + " line " + std::to_string(line_number);
    const auto field = [&](const std::string& name) -> std::string {
      const auto it = column.find(name);
      return it != column.end() && it->second < fields.size() ? fields[it->second] : std::string();
    };
    const auto number = [&](const std::string& name, float scale) -> float {
      const std::string text = field(name);
      if (text.empty()) return 0.0f;
      try {
        return std::stof(text) * scale;
      } catch (const std::exception&) {
        throw Error(ErrorCode::kInvalidInput, where + ": " + name + " '" + text + "' is not a number");
      }
    };
    TrainingMesh mesh;
    mesh.category = field("category");
    const std::string relative = field("path");
    if (mesh.category.empty() || relative.empty()) throw Error(ErrorCode::kInvalidInput, where + ": empty category or path");
    mesh.path = fs::path(relative).is_absolute() ? relative : (base / relative).string();
    // Sizes in metres (width_m...) or, as in Sweet Home 3D catalogues, centimetres (width_cm...).
    int d = 0;
    for (const char* axis : {"width", "depth", "height"}) {
      mesh.placement.size[d++] = number(std::string(axis) + "_m", 1.0f) + number(std::string(axis) + "_cm", 0.01f);
    }
    if (mesh.placement.size.isZero()) {
      mesh.placement.size = Eigen::Vector3f(0, 0, defaultCategorySize(mesh.category).z());
      mesh.placement.uniform = true;  // unknown proportions: keep the mesh's own
    }
    const std::string up = field("up");
    if (up == "z" || up == "Z") {
      mesh.placement.up = UpAxis::kZ;
    } else if (!up.empty() && up != "y" && up != "Y") {
      throw Error(ErrorCode::kInvalidInput, where + ": up '" + up + "' must be y or z");
    }
    const std::string rotation = field("rotation").empty() ? field("modelRotation") : field("rotation");
    if (!rotation.empty()) {
      std::stringstream s(rotation);
      Eigen::Matrix3f r;
      for (int i = 0; i < 9; ++i) {
        if (!(s >> r(i / 3, i % 3))) {
          throw Error(ErrorCode::kInvalidInput, where + ": rotation '" + rotation + "' is not 9 numbers (row-major 3x3)");
        }
      }
      mesh.placement.pre_rotation = r;
    }
    mesh.credit = field("credit");
    if (mesh.credit.empty() && !field("creator").empty()) mesh.credit = field("creator") + ", " + field("license");
    meshes.push_back(std::move(mesh));
  }
  if (meshes.empty()) throw Error(ErrorCode::kInvalidInput, "manifest " + path + " lists no meshes");
  return meshes;
}

std::vector<TrainingMesh> meshesFromFolders(const std::string& root) {
  if (!fs::is_directory(root)) throw Error(ErrorCode::kNotFound, "training folder " + root + " does not exist");
  std::vector<fs::path> folders;
  for (const auto& entry : fs::directory_iterator(root)) {
    if (entry.is_directory()) folders.push_back(entry.path());
  }
  std::sort(folders.begin(), folders.end());
  std::vector<TrainingMesh> meshes;
  for (const auto& folder : folders) {
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(folder)) {
      std::string ext = entry.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
      if (entry.is_regular_file() && (ext == ".obj" || ext == ".off" || ext == ".ply")) files.push_back(entry.path());
    }
    std::sort(files.begin(), files.end());
    const std::string category = folder.filename().string();
    for (const auto& file : files) {
      TrainingMesh mesh;
      mesh.category = category;
      mesh.path = file.string();
      mesh.placement.size = Eigen::Vector3f(0, 0, defaultCategorySize(category).z());
      mesh.placement.uniform = true;
      meshes.push_back(std::move(mesh));
    }
  }
  if (meshes.empty()) {
    throw Error(ErrorCode::kInvalidInput, "training folder " + root + " has no ROOT/<category>/*.{obj,off,ply} meshes");
  }
  return meshes;
}

std::vector<TrainingScan> scanMeshes(const std::vector<TrainingMesh>& meshes, const TrainingParams& params) {
  const auto start = Clock::now();
  const int threads = threadCount(params);
  std::vector<Mesh> placed(meshes.size());
  std::vector<int> model_index(meshes.size());
  std::map<std::string, int> per_category;
  for (size_t i = 0; i < meshes.size(); ++i) model_index[i] = per_category[meshes[i].category]++;
  parallelFor(static_cast<int>(meshes.size()), threads, [&](int i) {
    placed[static_cast<size_t>(i)] = placeMesh(loadMesh(meshes[static_cast<size_t>(i)].path), meshes[static_cast<size_t>(i)].placement);
  });
  if (params.progress) params.progress("loaded " + std::to_string(meshes.size()) + " meshes in " + fixed(secondsSince(start), 1) + " s");

  std::vector<std::vector<Eigen::Isometry3f>> views(meshes.size());
  std::vector<std::pair<int, int>> jobs;  // (mesh, view)
  for (size_t m = 0; m < meshes.size(); ++m) {
    views[m] = viewRing(placed[m], params.views);
    for (size_t v = 0; v < views[m].size(); ++v) jobs.emplace_back(static_cast<int>(m), static_cast<int>(v));
  }
  std::vector<TrainingScan> scans(jobs.size());
  std::mutex progress_mutex;
  int done = 0;
  parallelFor(static_cast<int>(jobs.size()), threads, [&](int j) {
    const auto scan_start = Clock::now();
    const auto [m, v] = jobs[static_cast<size_t>(j)];
    const TrainingMesh& mesh = meshes[static_cast<size_t>(m)];
    NoiseParams noise = params.noise;
    noise.seed += static_cast<uint32_t>(j);  // independent noise per scan, reproducible
    const DepthImage depth = renderDepth({&placed[static_cast<size_t>(m)]}, views[static_cast<size_t>(m)][static_cast<size_t>(v)],
                                         params.intrinsics, noise);
    const std::string source = mesh.path + " view " + std::to_string(v + 1);
    TrainingScan& scan = scans[static_cast<size_t>(j)];
    scan.category = mesh.category;
    scan.model_index = model_index[static_cast<size_t>(m)];
    scan.object_center = placed[static_cast<size_t>(m)].bounds().center();
    scan.features = extractFeatures(depthImageToWorldScene(depth, source), params.front_end, false).features;
    scan.keypoint_box = fitOrientedBox(scan.features.positions);
    if (params.progress) {
      std::lock_guard<std::mutex> lock(progress_mutex);
      params.progress("scanned " + std::to_string(++done) + "/" + std::to_string(jobs.size()) + " " + mesh.category +
                      " " + std::to_string(scan.model_index + 1) + "/" + std::to_string(per_category[mesh.category]) +
                      " view " + std::to_string(v + 1) + ": " + std::to_string(scan.features.size()) + " keypoints, " +
                      fixed(secondsSince(scan_start), 2) + " s");
    }
  });
  if (params.progress) params.progress("scanning took " + fixed(secondsSince(start), 1) + " s");
  return scans;
}

Model trainFromScans(const std::vector<TrainingScan>& scans, const std::vector<std::string>& categories,
                     const TrainingParams& params) {
  const auto report = [&](const std::string& line) {
    if (params.progress) params.progress(line);
  };
  if (categories.empty()) throw Error(ErrorCode::kInvalidInput, "training: no categories");
  if (!(params.threshold_floor >= 0 && params.threshold_floor <= 1)) {
    throw Error(ErrorCode::kInvalidInput,
                "training: threshold_floor " + std::to_string(params.threshold_floor) + " is not in [0, 1]");
  }
  if (!params.global_codebook && !params.separated_codebooks) {
    throw Error(ErrorCode::kInvalidInput, "training: neither a global nor separated codebooks requested");
  }
  const int threads = threadCount(params);
  Model model;
  model.front_end = params.front_end;
  model.trained_knn = params.knn;
  model.trained_knn.strategy = ActivationStrategy::kKnn;
  model.trained_cutoff = params.cutoff;
  model.trained_cutoff.strategy = ActivationStrategy::kCutoff;

  std::map<std::string, int> index_of;
  std::vector<std::vector<const TrainingScan*>> scans_of(categories.size());
  std::vector<int> models_of(categories.size(), 0);
  for (size_t c = 0; c < categories.size(); ++c) {
    if (!index_of.emplace(categories[c], static_cast<int>(c)).second) {
      throw Error(ErrorCode::kInvalidInput, "training: category '" + categories[c] + "' is listed twice");
    }
  }
  for (const auto& scan : scans) {
    const auto it = index_of.find(scan.category);
    if (it == index_of.end()) throw Error(ErrorCode::kInvalidInput, "training: scan of unlisted category '" + scan.category + "'");
    scans_of[static_cast<size_t>(it->second)].push_back(&scan);
    models_of[static_cast<size_t>(it->second)] = std::max(models_of[static_cast<size_t>(it->second)], scan.model_index + 1);
  }
  for (size_t c = 0; c < categories.size(); ++c) {
    size_t keypoints = 0;
    for (const auto* s : scans_of[c]) keypoints += s->features.size();
    if (models_of[c] < 2 || keypoints == 0) {
      throw Error(ErrorCode::kInvalidInput, "training: category '" + categories[c] + "' has " +
                                                std::to_string(models_of[c]) + " models and " + std::to_string(keypoints) +
                                                " keypoints; leave-one-out thresholds need at least 2 models with keypoints");
    }
    CategoryModel category;
    category.name = categories[c];
    const auto bin = params.bin_sizes.find(category.name);
    category.bin_size = bin != params.bin_sizes.end() ? bin->second : params.default_bin_size;
    category.training_models = models_of[c];
    category.training_scans = static_cast<int>(scans_of[c].size());

    // Box limits from the single-view keypoint boxes, which is what a hypothesis' support is.
    std::vector<double> volumes, edges;
    for (const auto* s : scans_of[c]) {
      if (s->features.size() == 0) continue;
      volumes.push_back(s->keypoint_box.volume());
      edges.push_back(s->keypoint_box.longestEdge());
    }
    const MeanStd volume = meanStd(volumes), edge = meanStd(edges);
    category.box.mean_volume = static_cast<float>(volume.mean);
    category.box.std_volume = static_cast<float>(volume.std);
    category.box.mean_max_edge = static_cast<float>(edge.mean);
    category.box.std_max_edge = static_cast<float>(edge.std);
    category.box.min_volume = static_cast<float>(std::max(0.0, *std::min_element(volumes.begin(), volumes.end()) - volume.std));
    category.box.max_volume = static_cast<float>(*std::max_element(volumes.begin(), volumes.end()) + volume.std);
    category.box.max_edge = static_cast<float>(*std::max_element(edges.begin(), edges.end()) + edge.std);
    model.categories.push_back(std::move(category));
  }

  std::vector<CodebookType> types;
  if (params.global_codebook) types.push_back(CodebookType::kGlobal);
  if (params.separated_codebooks) types.push_back(CodebookType::kSeparated);
  for (CodebookType type : types) {
    // Codebooks: one over every category, or one per category.
    std::vector<const Codebook*> codebook_of(categories.size());
    if (type == CodebookType::kGlobal) {
      std::vector<const TrainingScan*> all;
      for (const auto& s : scans) all.push_back(&s);
      const auto start = Clock::now();
      const DescriptorMatrix descriptors = stackDescriptors(all);
      const KMeansResult km = kmeans(descriptors, params.global_kmeans);
      model.global_codebook = Codebook(km.centers);
      report("global codebook: k-means of " + std::to_string(descriptors.rows()) + " descriptors into " +
             std::to_string(km.centers.rows()) + " codewords, " + std::to_string(km.iterations) +
             " iterations, mean distance " + fixed(km.mean_distance, 3) + ", " + fixed(secondsSince(start), 1) + " s");
      std::fill(codebook_of.begin(), codebook_of.end(), &*model.global_codebook);
    } else {
      for (size_t c = 0; c < categories.size(); ++c) {
        const auto start = Clock::now();
        const DescriptorMatrix descriptors = stackDescriptors(scans_of[c]);
        const KMeansResult km = kmeans(descriptors, params.separated_kmeans);
        model.categories[c].own_codebook = Codebook(km.centers);
        codebook_of[c] = &*model.categories[c].own_codebook;
        report(categories[c] + " codebook: k-means of " + std::to_string(descriptors.rows()) + " descriptors into " +
               std::to_string(km.centers.rows()) + " codewords, " + std::to_string(km.iterations) +
               " iterations, mean distance " + fixed(km.mean_distance, 3) + ", " + fixed(secondsSince(start), 1) + " s");
      }
    }

    // Votes: each training keypoint's vector to the object centre in its LRF, under its 1-NN codeword.
    const auto votes_start = Clock::now();
    std::vector<std::vector<RawVote>> raw(categories.size());
    for (size_t c = 0; c < categories.size(); ++c) {
      for (const auto* s : scans_of[c]) {
        for (const auto& a : codebook_of[c]->activate(s->features.descriptors, {ActivationStrategy::kKnn, 1, 0})) {
          const auto k = static_cast<size_t>(a.keypoint);
          raw[c].push_back({a.codeword, s->model_index,
                            s->features.lrfs[k] * (s->object_center - s->features.positions[k])});
        }
      }
      VoteTable table = packVotes(raw[c], codebook_of[c]->size());
      (type == CodebookType::kGlobal ? model.categories[c].global_votes : model.categories[c].own_votes) = std::move(table);
    }
    report(std::string(toString(type)) + " votes stored in " + fixed(secondsSince(votes_start), 1) + " s");

    // Leave-one-out: the codebook stays fixed, the held-out model's votes are removed, and each
    // of its scans is scored at its true centre; threshold = mean - std over those scores.
    const auto loo_start = Clock::now();
    const std::vector<ActivationParams> activations{model.trained_knn, model.trained_cutoff};
    const std::vector<VoteWeighting> weightings{VoteWeighting::kCategorization, VoteWeighting::kLocalization,
                                                VoteWeighting::kActivation};
    for (size_t c = 0; c < categories.size(); ++c) {
      CategoryModel& category = model.categories[c];
      std::vector<Model> held_out(static_cast<size_t>(models_of[c]));
      for (int m = 0; m < models_of[c]; ++m) {
        CategoryModel reduced;
        reduced.name = category.name;
        reduced.bin_size = category.bin_size;
        (type == CodebookType::kGlobal ? reduced.global_votes : reduced.own_votes) =
            packVotes(raw[c], codebook_of[c]->size(), m);
        held_out[static_cast<size_t>(m)].categories.push_back(std::move(reduced));
      }
      const auto& cat_scans = scans_of[c];
      // scores[scan][activation * 3 + weighting]
      std::vector<std::array<double, 6>> scores(cat_scans.size());
      parallelFor(static_cast<int>(cat_scans.size()), threads, [&](int i) {
        const TrainingScan& s = *cat_scans[static_cast<size_t>(i)];
        const Model& without = held_out[static_cast<size_t>(s.model_index)];
        for (size_t a = 0; a < activations.size(); ++a) {
          const auto activated = codebook_of[c]->activate(s.features.descriptors, activations[a]);
          for (size_t w = 0; w < weightings.size(); ++w) {
            const auto votes = castVotes(without, 0, s.features, activated, {type, activations[a], weightings[w]});
            scores[static_cast<size_t>(i)][a * 3 + w] = scoreAt(votes, s.object_center, category.bin_size);
          }
        }
      });
      std::string line = category.name + " " + toString(type) + " thresholds:";
      bool floored_any = false, useless_any = false;
      for (size_t a = 0; a < activations.size(); ++a) {
        for (size_t w = 0; w < weightings.size(); ++w) {
          std::vector<double> values;
          for (const auto& s : scores) values.push_back(s[a * 3 + w]);
          const MeanStd stats = meanStd(values);
          const double seed_rule = stats.mean - stats.std, floor = params.threshold_floor * stats.mean;
          const bool floored = seed_rule < floor;
          const float threshold = static_cast<float>(floored ? floor : seed_rule);
          const ThresholdKey key{type, activations[a].strategy, weightings[w]};
          category.thresholds[key] = threshold;
          category.threshold_stats[key] = {static_cast<float>(stats.mean), static_cast<float>(stats.std)};
          line += std::string(" ") + toString(activations[a].strategy) + "/" + toString(weightings[w]) + "=" +
                  fixed(threshold, 3);
          if (floored) line += "(floored; mean " + fixed(stats.mean, 3) + " - std " + fixed(stats.std, 3) + ")";
          floored_any |= floored;
          if (!(threshold > 0)) line += "(!)";
          useless_any |= !(threshold > 0);
        }
      }
      if (floored_any) {
        line += "  floored = mean - std fell below " + fixed(params.threshold_floor, 2) +
                " x the mean held-out score (few or dissimilar training models)";
      }
      if (useless_any) line += "  (!) = a threshold <= 0 admits every peak: pass a minimum score when detecting";
      report(line);
    }
    report(std::string(toString(type)) + " leave-one-out thresholds in " + fixed(secondsSince(loo_start), 1) + " s");
  }
  return model;
}

Model train(const std::vector<TrainingMesh>& meshes, const TrainingParams& params) {
  if (meshes.empty()) throw Error(ErrorCode::kInvalidInput, "training: no meshes");
  const auto start = Clock::now();
  std::vector<std::string> categories;
  for (const auto& m : meshes) {
    if (std::find(categories.begin(), categories.end(), m.category) == categories.end()) categories.push_back(m.category);
  }
  const std::vector<TrainingScan> scans = scanMeshes(meshes, params);
  Model model = trainFromScans(scans, categories, params);
  for (const auto& m : meshes) model.provenance.meshes.push_back(m.category + "\t" + m.path + "\t" + m.credit);
  model.provenance.scans = static_cast<int>(scans.size());
  model.provenance.created = utcNow();
  model.provenance.code_version = codeVersion();
  model.provenance.command = params.command;
  if (params.progress) params.progress("training took " + fixed(secondsSince(start), 1) + " s");
  return model;
}

}  // namespace ism
