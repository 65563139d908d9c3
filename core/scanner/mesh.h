#pragma once
// Triangle meshes for the virtual scanner: loading (OBJ with polygons of any size, OFF, PLY)
// and putting a CAD mesh into the world at real size, +z up.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace ism {

struct Mesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<Eigen::Vector3i> triangles;  // polygons are fan-triangulated on load
  Eigen::AlignedBox3f bounds() const;
};

// Chosen by extension (.obj, .off, .ply). Throws ism::Error naming the file and the problem.
Mesh loadMesh(const std::string& path);

enum class UpAxis { kY, kZ };

struct MeshPlacement {
  UpAxis up = UpAxis::kY;  // PSB and Sweet Home 3D meshes are Y-up
  // Applied first, in the mesh's own frame (Sweet Home 3D's modelRotation).
  Eigen::Matrix3f pre_rotation = Eigen::Matrix3f::Identity();
  // Real size (m) after the up-axis change: x = width, y = depth, z = height. A zero
  // component is derived from the others; all zero keeps the mesh's own size.
  Eigen::Vector3f size = Eigen::Vector3f::Zero();
  // true: one scale for all axes, keeping the mesh's proportions. With width, depth and height
  // all given, the scale whose box fits them best (the geometric mean of the three ratios, the
  // footprint's longer side against the longer given one, since a mesh's front is not known);
  // else the height's ratio, or the first given extent's.
  bool uniform = false;
  // Whether `size` is a guess (the category's typical size, for a mesh that came without one)
  // rather than the object's: it then says nothing about the sizes the category comes in.
  bool size_guessed = false;
};

// Returns the mesh +z up, scaled, its bounding box centred on x=y=0 and standing on z=0.
Mesh placeMesh(const Mesh& mesh, const MeshPlacement& placement);

Mesh transformed(const Mesh& mesh, const Eigen::Isometry3f& pose);

// Points spread evenly over the mesh's surface: an area-weighted random sample thinned to one
// point per cube of edge `spacing`, then at most `max_points` of them, in random order so that
// any prefix is an even sample too. The same for the same seed.
std::vector<Eigen::Vector3f> sampleSurface(const Mesh& mesh, float spacing, size_t max_points, uint32_t seed = 1);

}  // namespace ism
