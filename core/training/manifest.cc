#include "core/training/manifest.h"

#include <algorithm>
#include <cctype>
#include <exception>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "core/common/error.h"

namespace ism {
namespace {

namespace fs = std::filesystem;

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
      // Unknown proportions: the mesh's own, at the scale that best fits the category's typical size.
      mesh.placement.size = defaultCategorySize(mesh.category);
      mesh.placement.uniform = true;
      mesh.placement.size_guessed = true;
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
      mesh.placement.size = defaultCategorySize(category);
      mesh.placement.uniform = true;
      mesh.placement.size_guessed = true;
      meshes.push_back(std::move(mesh));
    }
  }
  if (meshes.empty()) {
    throw Error(ErrorCode::kInvalidInput, "training folder " + root + " has no ROOT/<category>/*.{obj,off,ply} meshes");
  }
  return meshes;
}

}  // namespace ism
