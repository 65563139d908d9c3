#pragma once
// The models the server answers with. Each is an immutable std::shared_ptr<const LoadedModel>:
// a request takes its pointer once and keeps it, so loading, replacing or unloading a model
// never disturbs a request (or a stream frame) that is already running. Changes to the set
// (load, unload, reload) happen one at a time, each whole, so that any two that overlap end as
// if one had come after the other; requests only wait for the name -> pointer map, never for a
// file being read.
#include <map>
#include <memory>
#include <mutex>
#include <set>
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
  static constexpr size_t kDefaultMaxFileBytes = size_t{256} << 20;

  // `directory` holds the model files: loadDirectory() and reload() read its *.ismm, load() only
  // files in it (may be empty: none). Files larger than `max_file_bytes` are refused.
  explicit ModelRegistry(std::string directory, size_t max_file_bytes = kDefaultMaxFileBytes)
      : directory_(std::move(directory)), max_file_bytes_(max_file_bytes) {}

  // Loads every *.ismm of the directory, name = file stem. Throws on the first bad file: a
  // server must not start with part of its models silently missing.
  void loadDirectory();

  // Reads the file and then swaps it in under `name`. `path` is relative to the directory or
  // absolute, and must lie inside it (a caller may not read other files of the server). Throws
  // ism::Error (outside the directory, not a regular file, too large, version, CRC).
  std::shared_ptr<const LoadedModel> load(const std::string& name, const std::string& path);
  // Error(kNotFound) when no such model is loaded. The model stays unloaded until load() names
  // it again (or the server restarts), even when its file is in the directory: reload() does not
  // bring it back.
  void unload(const std::string& name);
  // Re-reads every loaded model from its file and loads the directory's files that are not
  // loaded (but those unloaded by unload()). A model whose file fails or is gone keeps its
  // loaded version, and the failure is reported.
  std::vector<LoadFailure> reload();

  // Empty name: the only model, else the one named "default". Error(kNotFound) names the
  // models that are loaded.
  std::shared_ptr<const LoadedModel> get(const std::string& name) const;
  std::vector<std::shared_ptr<const LoadedModel>> list() const;
  size_t size() const;

 private:
  // Reads a model file into a LoadedModel without registering it.
  std::shared_ptr<const LoadedModel> readModel(const std::string& name, const std::string& path) const;
  // `path` resolved against the directory; Error(kInvalidInput) when it leads out of it.
  std::string pathInDirectory(const std::string& path) const;
  void put(std::shared_ptr<const LoadedModel> model);
  std::string loadedNames() const;  // caller holds mutex_

  std::string directory_;
  size_t max_file_bytes_;
  std::mutex changes_;  // held through each change, file reads included
  std::set<std::string> unloaded_;  // by unload(), until load() names them again
  mutable std::mutex mutex_;  // guards models_ only
  std::map<std::string, std::shared_ptr<const LoadedModel>> models_;
};

}  // namespace ism::server
