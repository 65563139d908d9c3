#pragma once
// Procedural furniture built from boxes (table top on four legs, chair with a back, couch with
// arms...), placed +z up on z=0, so tests can train and recognise without any data files.
// `variant` changes proportions a little so that several "models" of a category differ.
#include <string>
#include <vector>

#include "core/scanner/mesh.h"

namespace ism::testing {

Mesh boxMesh(const Eigen::Vector3f& min_corner, const Eigen::Vector3f& max_corner);
Mesh merge(const Mesh& a, const Mesh& b);

// The points of a box's faces every 4 cm, as a training shape's surface (TrainingObject::surface).
std::vector<Eigen::Vector3f> boxSurface(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi);

// category: "dining_table", "dining_chair", "office_chair", "couch"
Mesh syntheticFurniture(const std::string& category, int variant);

}  // namespace ism::testing
