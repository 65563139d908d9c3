#pragma once
// PCD parsing of our own, from bytes in memory. PCL 1.13's PCDReader trusts its header: it
// allocates POINTS x point size before reading a byte of the body (12.9 GB for a 240-byte file),
// overruns its buffers when SIZE, TYPE and COUNT disagree with FIELDS, and frees a bad pointer on
// some ASCII bodies (all found by tests/fuzz). This reader checks the whole header against the
// size of the body before it allocates, and never reads outside the bytes it is given.
//
// Supported: PCD v0.5-0.7 headers (FIELDS or COLUMNS, SIZE, TYPE, COUNT, WIDTH, HEIGHT,
// VIEWPOINT, POINTS), bodies `ascii`, `binary` and `binary_compressed` (LZF, fields stored one
// after another as PCL writes them), every PCD type (I/U 1, 2, 4, 8 bytes; F 4, 8 bytes).
#include <pcl/PCLPointCloud2.h>

#include <Eigen/Geometry>
#include <string>
#include <string_view>

namespace ism {

struct PcdCloud {
  // Fields at consecutive offsets, points interleaved (point_step bytes each), width x height.
  pcl::PCLPointCloud2 blob;
  Eigen::Vector4f origin = Eigen::Vector4f::Zero();
  Eigen::Quaternionf orientation = Eigen::Quaternionf::Identity();
};

// Throws Error(kInvalidInput) whose message starts with `source` and says what is wrong.
PcdCloud parsePcd(std::string_view bytes, const std::string& source);

}  // namespace ism
