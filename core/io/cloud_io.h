#pragma once
// Reading and writing cloud files: PCD and PLY (organized or not, with or without colour).
// Reading PLY and writing PCD go through pcl_io (library ism_io); the in-memory decoders of
// scene_bytes.h (library ism_io_bytes) come with this header, so a tool reads any input from one
// include. NaN/Inf points are dropped. Every failure throws ism::Error whose message names the
// file and the problem.
#include <string>
#include <vector>

#include "core/common/types.h"
#include "core/io/scene_bytes.h"

namespace ism {

// .pcd or .ply, chosen by extension (case-insensitive).
Scene loadCloudFile(const std::string& path);

// Writing, for debugging and for the shipped sample scene. savePcd writes binary PCD with the
// sensor pose as VIEWPOINT; an organized scene is written organized (NaN where no point was
// kept) so that loading it back restores the pixel indices.
void savePcd(const Scene& scene, const std::string& path);
// `colors` (0..255 per channel) is empty for uncoloured points or index-aligned with `points`.
enum class PlyEncoding { kAscii, kBinary };
void savePlyPoints(const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3i>& colors,
                   const std::string& path, PlyEncoding encoding = PlyEncoding::kBinary);

}  // namespace ism
