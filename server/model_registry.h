#pragma once
// The models the server answers with. Each is an immutable std::shared_ptr<const LoadedModel>:
// a request takes its pointer once and keeps it, so loading, replacing or unloading a model
// never disturbs a request (or a stream frame) that is already running. The mutex only guards
// the name -> pointer map; files are read outside it.
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "core/model/model.h"
#include "ism/v1/service.pb.h"

namespace ism::server {

struct LoadedModel {
  std::string name;
  Model model;
  // Everything ListModels/GetModel report, built once from the file's own ModelData (so the
  // wire shows exactly what the file holds) without the codebooks and votes.
  v1::ModelInfo info;
};

struct LoadFailure {
  std::string name;
  std::string path;
  std::string message;
};

class ModelRegistry {
 public:
  // `directory` is where ReloadModels looks for new *.ismm files (may be empty: none).
  explicit ModelRegistry(std::string directory) : directory_(std::move(directory)) {}

  // Loads every *.ismm of the directory, name = file stem. Throws on the first bad file: a
  // server must not start with part of its models silently missing.
  void loadDirectory();

  // Reads the file and then swaps it in under `name`. Throws ism::Error (file, version, CRC).
  std::shared_ptr<const LoadedModel> load(const std::string& name, const std::string& path);
  // Error(kNotFound) when no such model is loaded.
  void unload(const std::string& name);
  // Re-reads every loaded model from its file and loads new files of the directory; a file
  // that fails keeps its previous version loaded and is reported.
  std::vector<LoadFailure> reload();

  // Empty name: the only model, else the one named "default". Error(kNotFound) names the
  // models that are loaded.
  std::shared_ptr<const LoadedModel> get(const std::string& name) const;
  std::vector<std::shared_ptr<const LoadedModel>> list() const;
  size_t size() const;

 private:
  std::string loadedNames() const;  // caller holds mutex_

  std::string directory_;
  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<const LoadedModel>> models_;
};

}  // namespace ism::server
