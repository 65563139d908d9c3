#pragma once
// Training sets: which meshes to train from, with each mesh's category, real size and
// orientation, from a manifest (TSV) or from one folder per category.
#include <string>
#include <vector>

#include "core/scanner/scanner.h"

namespace ism {

struct TrainingMesh {
  std::string category;
  std::string path;
  MeshPlacement placement;
  std::string credit;  // creator and licence, stored in the model's provenance
};

// Manifest: TSV with header "category path [width_m depth_m height_m up rotation credit]". Rows of
// the category kBackgroundCategory ("background") are background meshes (background.h).
std::vector<TrainingMesh> readManifest(const std::string& path);
// Folders: ROOT/<category>/*.{obj,off,ply}, sizes from defaultCategorySize().
std::vector<TrainingMesh> meshesFromFolders(const std::string& root);
// Typical real size (w, d, h in m) of a category, for CAD meshes normalised to a unit cube.
Eigen::Vector3f defaultCategorySize(const std::string& category);

}  // namespace ism
