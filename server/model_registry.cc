#include "server/model_registry.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>

#include "core/common/error.h"
#include "core/model/model_file.h"

namespace ism::server {
namespace fs = std::filesystem;

namespace {

std::vector<fs::path> modelFiles(const std::string& directory) {
  std::vector<fs::path> files;
  if (directory.empty()) return files;
  std::error_code ec;
  if (!fs::is_directory(directory, ec)) {
    throw Error(ErrorCode::kNotFound, "model directory " + directory + " does not exist");
  }
  for (const auto& entry : fs::directory_iterator(directory)) {
    if (entry.is_regular_file() && entry.path().extension() == ".ismm") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

// Names travel in messages, logs and metric labels: short, and nothing that needs escaping.
void checkModelName(const std::string& name, const std::string& path) {
  constexpr size_t kMaxName = 64;
  const bool valid = !name.empty() && name.size() <= kMaxName && name[0] != '.' &&
                     std::all_of(name.begin(), name.end(), [](char c) {
                       return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-';
                     });
  if (!valid) {
    throw Error(ErrorCode::kInvalidInput, "a model name (here of " + std::to_string(name.size()) +
                                              " bytes, for " + path.substr(0, 256) + ") must be 1 to " +
                                              std::to_string(kMaxName) +
                                              " letters, digits, '.', '_' or '-', not starting with '.'");
  }
}

// A name a client asked for, in quotes; no loaded name is longer than this.
std::string quoted(const std::string& name) {
  constexpr size_t kShown = 64;
  if (name.size() <= kShown) return "'" + name + "'";
  return "'" + name.substr(0, kShown) + "...' (" + std::to_string(name.size()) + " bytes)";
}

}  // namespace

std::shared_ptr<const LoadedModel> ModelRegistry::readModel(const std::string& name, const std::string& path) const {
  checkModelName(name, path);
  auto start = std::chrono::steady_clock::now();
  // Read once: the same bytes give the model, its description and its version, so they agree.
  ModelFileContents file = readModelFile(path, max_file_bytes_);
  auto loaded = std::make_shared<LoadedModel>();
  loaded->name = name;
  loaded->model = std::move(file.model);
  const Model& model = loaded->model;
  const v1::ModelData& data = file.description;
  v1::ModelInfo& info = loaded->info;
  info.set_name(name);
  info.set_path(fs::absolute(path).string());
  info.set_version(file.version);
  info.set_format_version(file.format_version);
  *info.mutable_front_end() = data.front_end();
  *info.mutable_trained_knn() = data.trained_knn();
  *info.mutable_trained_cutoff() = data.trained_cutoff();
  info.set_global_codebook_size(model.global_codebook ? model.global_codebook->size() : 0);
  info.set_draws(static_cast<uint32_t>(1 + model.draws.size()));
  for (size_t i = 0; i < model.categories.size(); ++i) {
    const auto& category = data.categories(static_cast<int>(i));
    const CategoryModel& trained = model.categories[i];
    auto* out = info.add_categories();
    out->set_name(category.name());
    out->set_bin_size(category.bin_size());
    *out->mutable_box() = category.box();
    out->set_own_codebook_size(trained.own_codebook ? trained.own_codebook->size() : 0);
    out->set_global_votes(trained.global_votes.vectors.size());
    out->set_own_votes(trained.own_votes.vectors.size());
    *out->mutable_thresholds() = category.thresholds();
    out->set_training_models(category.training_models());
    out->set_training_scans(category.training_scans());
  }
  *info.mutable_provenance() = data.provenance();
  info.set_loaded_at_unix_ms(std::chrono::duration_cast<std::chrono::milliseconds>(
                                 std::chrono::system_clock::now().time_since_epoch())
                                 .count());
  info.set_load_ms(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  return loaded;
}

std::string ModelRegistry::pathInDirectory(const std::string& path) const {
  if (directory_.empty()) {
    throw Error(ErrorCode::kInvalidInput, "LoadModel: the server has no model folder (--models) to load from");
  }
  fs::path root = fs::absolute(directory_).lexically_normal();
  if (root.filename().empty()) root = root.parent_path();  // a trailing '/'
  const fs::path resolved = (fs::path(path).is_absolute() ? fs::path(path) : root / path).lexically_normal();
  const fs::path inside = resolved.lexically_relative(root);
  if (inside.empty() || inside == "." || *inside.begin() == "..") {
    throw Error(ErrorCode::kInvalidInput, "LoadModel: path '" + path + "' is not in the model folder " +
                                              root.string() + ": only files there are loaded");
  }
  return resolved.string();
}

void ModelRegistry::loadDirectory() {
  std::lock_guard<std::mutex> changing(changes_);
  for (const auto& file : modelFiles(directory_)) put(readModel(file.stem().string(), file.string()));
}

std::shared_ptr<const LoadedModel> ModelRegistry::load(const std::string& name, const std::string& path) {
  const std::string file = pathInDirectory(path);  // before anything on disk is touched
  std::lock_guard<std::mutex> changing(changes_);
  auto loaded = readModel(name, file);
  unloaded_.erase(name);
  put(loaded);
  return loaded;
}

void ModelRegistry::unload(const std::string& name) {
  std::lock_guard<std::mutex> changing(changes_);
  std::lock_guard<std::mutex> lock(mutex_);
  if (models_.erase(name) == 0) {
    throw Error(ErrorCode::kNotFound, "model " + quoted(name) + " is not loaded (loaded: " + loadedNames() + ")");
  }
  unloaded_.insert(name);
}

std::vector<LoadFailure> ModelRegistry::reload() {
  std::lock_guard<std::mutex> changing(changes_);
  std::map<std::string, std::string> sources;  // name -> path
  for (const auto& model : list()) sources[model->name] = model->info.path();
  std::vector<LoadFailure> failures;
  try {
    for (const auto& file : modelFiles(directory_)) {
      if (unloaded_.count(file.stem().string()) == 0) {
        sources.emplace(file.stem().string(), fs::absolute(file).string());
      }
    }
  } catch (const Error& e) {
    failures.push_back({"", directory_, e.what()});
  }
  for (const auto& [name, path] : sources) {
    try {
      put(readModel(name, path));
    } catch (const Error& e) {
      failures.push_back({name, path, e.what()});
    }
  }
  return failures;
}

void ModelRegistry::put(std::shared_ptr<const LoadedModel> model) {
  std::lock_guard<std::mutex> lock(mutex_);
  models_[model->name] = std::move(model);
}

std::shared_ptr<const LoadedModel> ModelRegistry::get(const std::string& name) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (name.empty()) {
    if (models_.size() == 1) return models_.begin()->second;
    auto it = models_.find("default");
    if (it != models_.end()) return it->second;
    throw Error(ErrorCode::kNotFound, models_.empty()
                                          ? std::string("no model is loaded")
                                          : "no model named in the request and none is called 'default' (loaded: " +
                                                loadedNames() + ")");
  }
  auto it = models_.find(name);
  if (it == models_.end()) {
    throw Error(ErrorCode::kNotFound, "unknown model " + quoted(name) + " (loaded: " + loadedNames() + ")");
  }
  return it->second;
}

std::vector<std::shared_ptr<const LoadedModel>> ModelRegistry::list() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::shared_ptr<const LoadedModel>> out;
  for (const auto& entry : models_) out.push_back(entry.second);
  return out;
}

size_t ModelRegistry::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return models_.size();
}

std::string ModelRegistry::loadedNames() const {
  if (models_.empty()) return "none";
  constexpr size_t kMaxListed = 16;  // keeps the message short however many are loaded
  std::string names;
  size_t listed = 0;
  for (const auto& entry : models_) {
    if (listed++ == kMaxListed) return names + " and " + std::to_string(models_.size() - kMaxListed) + " more";
    names += (names.empty() ? "" : ", ") + entry.first;
  }
  return names;
}

}  // namespace ism::server
