#include "core/io/cloud_io.h"

#include <pcl/PCLPointCloud2.h>
#include <pcl/exceptions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <limits>

#include "core/common/error.h"
#include "core/io/finite_points.h"
#include "core/io/file_bytes.h"
#include "core/io/pcd_reader.h"

namespace ism {
namespace {

using io_detail::collectFinite;

const pcl::PCLPointField* findField(const pcl::PCLPointCloud2& blob, const char* name) {
  for (const auto& field : blob.fields) {
    if (field.name == name) return &field;
  }
  return nullptr;
}

// A field must lie inside its point; the PCD parser guarantees it, PCL's PLY reader is checked.
void requireFieldInsidePoint(const pcl::PCLPointCloud2& blob, const pcl::PCLPointField& field, const std::string& path) {
  const size_t size = static_cast<size_t>(pcl::getFieldSize(field.datatype));
  if (size == 0 || static_cast<size_t>(field.offset) + size > blob.point_step) {
    throw Error(ErrorCode::kInvalidInput, path + ": field '" + field.name + "' (offset " +
                                              std::to_string(field.offset) + ", " + std::to_string(size) +
                                              " bytes) does not fit in a " + std::to_string(blob.point_step) +
                                              "-byte point: SIZE and TYPE disagree");
  }
}

// Coordinates come as float32 from PCL and most scanners, but as float64 from Open3D and some
// meshing tools; both are accepted, anything else is refused rather than reinterpreted.
const pcl::PCLPointField& coordinateField(const pcl::PCLPointCloud2& blob, const char* name,
                                          const std::string& path) {
  const auto* field = findField(blob, name);
  if (field == nullptr) throw Error(ErrorCode::kInvalidInput, path + ": has no '" + name + "' field");
  if (field->datatype != pcl::PCLPointField::FLOAT32 && field->datatype != pcl::PCLPointField::FLOAT64) {
    throw Error(ErrorCode::kInvalidInput, path + ": field '" + name + "' has type code " +
                                              std::to_string(field->datatype) + ", expected float32 or float64");
  }
  requireFieldInsidePoint(blob, *field, path);
  return *field;
}

float readCoordinate(const uint8_t* point_data, const pcl::PCLPointField& field) {
  if (field.datatype == pcl::PCLPointField::FLOAT32) {
    float value;
    std::memcpy(&value, point_data + field.offset, sizeof(value));
    return value;
  }
  double value;
  std::memcpy(&value, point_data + field.offset, sizeof(value));
  return static_cast<float>(value);
}

Scene sceneFromBlob(const pcl::PCLPointCloud2& blob, const Eigen::Vector4f& origin,
                    const Eigen::Quaternionf& orientation, const std::string& path) {
  const auto& fx = coordinateField(blob, "x", path);
  const auto& fy = coordinateField(blob, "y", path);
  const auto& fz = coordinateField(blob, "z", path);
  // PCD stores colour as a packed 4-byte "rgb"/"rgba" field; PCL's PLY reader packs
  // red/green/blue(/alpha) properties into the same fields.
  const pcl::PCLPointField* color = findField(blob, "rgb");
  if (color == nullptr) color = findField(blob, "rgba");
  if (color != nullptr && pcl::getFieldSize(color->datatype) != 4) color = nullptr;
  if (color != nullptr) requireFieldInsidePoint(blob, *color, path);
  const size_t count = static_cast<size_t>(blob.width) * blob.height;
  if (blob.data.size() < count * blob.point_step) {
    throw Error(ErrorCode::kInvalidInput, path + ": header announces " + std::to_string(count) +
                                              " points but the data holds fewer");
  }
  Scene scene = collectFinite(count, static_cast<int>(blob.width), static_cast<int>(blob.height), color != nullptr,
                              path, [&](size_t i, PointT& p) {
                                const uint8_t* data = blob.data.data() + i * blob.point_step;
                                p.x = readCoordinate(data, fx);
                                p.y = readCoordinate(data, fy);
                                p.z = readCoordinate(data, fz);
                                uint32_t packed = 0;
                                if (color != nullptr) std::memcpy(&packed, data + color->offset, 4);
                                // Alpha is meaningless for a scene and often stored as 0.
                                p.rgba = (packed & 0x00FFFFFFu) | 0xFF000000u;
                              });
  scene.sensor_origin = origin.head<3>();
  scene.sensor_orientation = orientation.normalized();
  return scene;
}

std::string lowercaseExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

void requireReadableFile(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status)) throw Error(ErrorCode::kNotFound, path + ": no such file");
  if (!std::filesystem::is_regular_file(status)) throw Error(ErrorCode::kIo, path + ": is not a regular file");
  if (!std::ifstream(path, std::ios::binary)) {
    throw Error(ErrorCode::kIo, path + ": cannot open for reading: " + std::strerror(errno));
  }
}

// PCL 1.13's PLYReader aborts the process (assert) on a header line that starts with a blank or
// holds a control character, on a vertex element whose colour is not one each of red, green and
// blue (or of diffuse_red, diffuse_green and diffuse_blue, which it reads as colour too), red before
// blue (the blue channel writes the packed colour where the red one began) and alpha after red,
// with a colour channel other than uchar, with a list property or with a second vertex element,
// and it allocates the header's vertex count before reading a vertex, gigabytes for a 100-byte file
// (all found by tests/fuzz): the header is checked first. Every vertex takes at least a byte of the
// file.
void requireSupportedPlyHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const auto file_size = static_cast<long long>(std::filesystem::file_size(path));
  std::string line;
  bool in_vertex = false;
  int vertex_elements = 0;
  std::vector<std::string> colour;  // the vertex element's colour channels, in order
  bool alpha_before_red = false;
  for (int n = 0; n < 10000 && std::getline(in, line); ++n) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto control = std::find_if(line.begin(), line.end(), [](unsigned char c) { return c < 0x20 || c == 0x7f; });
    if (control != line.end() || (!line.empty() && line[0] == ' ')) {
      throw Error(ErrorCode::kInvalidInput, path + ": PLY header line " + std::to_string(n + 1) +
                                                " starts with a blank or holds a control character");
    }
    std::istringstream words(line);
    std::string word;
    words >> word;
    if (word == "end_header") break;
    if (word == "element") {
      std::string name, count_text;
      words >> name >> count_text;
      in_vertex = name == "vertex";
      if (in_vertex && ++vertex_elements > 1) {
        throw Error(ErrorCode::kInvalidInput, path + ": the PLY header has a second vertex element");
      }
      long long count = -1;
      if (!(std::istringstream(count_text) >> count)) count = -1;
      if (in_vertex && (count < 0 || count > file_size)) {
        throw Error(ErrorCode::kInvalidInput, path + ": vertex count '" + count_text + "' does not fit a file of " +
                                                  std::to_string(file_size) + " bytes");
      }
    } else if (word == "property" && in_vertex) {
      std::string type, name;
      words >> type;
      if (type == "list") {
        throw Error(ErrorCode::kInvalidInput, path + ": the vertex element has a list property; only scalar "
                                                    "vertex properties (x, y, z, red, green, blue...) are supported");
      }
      words >> name;
      const std::string channel = name.rfind("diffuse_", 0) == 0 ? name.substr(8) : name;
      const bool color = channel == "red" || channel == "green" || channel == "blue";
      if ((color || name == "alpha") && type != "uchar" && type != "uint8") {
        throw Error(ErrorCode::kInvalidInput, path + ": vertex property " + name + " is " + type +
                                                  "; colour channels must be uchar");
      }
      if (color) colour.push_back(name);
      if (name == "alpha" && std::none_of(colour.begin(), colour.end(), [](const std::string& c) {
            return c == "red" || c == "diffuse_red";
          })) {
        alpha_before_red = true;
      }
    }
  }
  // Three channels of one naming, each once, red before blue.
  const auto named = [&](const std::string& prefix) {
    const auto at = [&](const std::string& name) { return std::find(colour.begin(), colour.end(), prefix + name); };
    return colour.size() == 3 && at("green") != colour.end() && at("blue") != colour.end() && at("red") < at("blue");
  };
  if ((!colour.empty() && !named("") && !named("diffuse_")) || alpha_before_red) {
    std::string names;
    for (const auto& c : colour) names += (names.empty() ? "" : ", ") + c;
    throw Error(ErrorCode::kInvalidInput,
                path + ": vertex colour needs one each of red, green and blue (or of diffuse_red, diffuse_green and "
                       "diffuse_blue), red before blue and alpha after red; the header has " +
                    (names.empty() ? std::string("none") : names) + (alpha_before_red ? " and alpha before red" : ""));
  }
}

template <class PointOut>
void writePcd(const Scene& scene, const std::string& path) {
  pcl::PointCloud<PointOut> out;
  const auto& in = scene.cloud->points;
  auto convert = [](const PointT& p) {
    PointOut q;
    pcl::copyPoint(p, q);
    return q;
  };
  if (!scene.pixel_index.empty()) {
    PointOut missing;
    pcl::copyPoint(PointT(), missing);
    missing.x = missing.y = missing.z = std::numeric_limits<float>::quiet_NaN();
    out.points.assign(static_cast<size_t>(scene.image_width) * scene.image_height, missing);
    for (size_t i = 0; i < in.size(); ++i) out.points[scene.pixel_index[i]] = convert(in[i]);
    out.width = static_cast<uint32_t>(scene.image_width);
    out.height = static_cast<uint32_t>(scene.image_height);
    out.is_dense = false;
  } else {
    out.points.reserve(in.size());
    for (const auto& p : in) out.points.push_back(convert(p));
    out.width = static_cast<uint32_t>(in.size());
    out.height = 1;
    out.is_dense = true;
  }
  out.sensor_origin_ = Eigen::Vector4f(scene.sensor_origin.x(), scene.sensor_origin.y(), scene.sensor_origin.z(), 0.0f);
  out.sensor_orientation_ = scene.sensor_orientation;
  int status = -1;
  try {
    status = pcl::PCDWriter().writeBinary(path, out);
  } catch (const pcl::PCLException& e) {
    throw Error(ErrorCode::kIo, path + ": cannot write PCD: " + e.what());
  }
  if (status < 0) throw Error(ErrorCode::kIo, path + ": cannot write PCD");
}

void requireConsistentPixels(const Scene& scene, const std::string& path) {
  if (!scene.cloud) throw Error(ErrorCode::kInvalidInput, path + ": scene '" + scene.source + "' has no cloud");
  if (scene.pixel_index.empty()) return;
  const size_t pixels = static_cast<size_t>(std::max(scene.image_width, 0)) * std::max(scene.image_height, 0);
  if (scene.pixel_index.size() != scene.cloud->size()) {
    throw Error(ErrorCode::kInvalidInput, path + ": scene '" + scene.source + "' has " +
                                              std::to_string(scene.pixel_index.size()) + " pixel indices for " +
                                              std::to_string(scene.cloud->size()) + " points");
  }
  for (int index : scene.pixel_index) {
    if (index < 0 || static_cast<size_t>(index) >= pixels) {
      throw Error(ErrorCode::kInvalidInput, path + ": scene '" + scene.source + "' has pixel index " +
                                                std::to_string(index) + " outside its " +
                                                std::to_string(scene.image_width) + "x" +
                                                std::to_string(scene.image_height) + " image");
    }
  }
}

}  // namespace

Scene loadCloudFile(const std::string& path) {
  const std::string ext = lowercaseExtension(path);
  if (ext != ".pcd" && ext != ".ply") {
    throw Error(ErrorCode::kInvalidInput, path + ": unsupported cloud format '" + ext + "' (expected .pcd or .ply)");
  }
  requireReadableFile(path);
  pcl::PCLPointCloud2 blob;
  Eigen::Vector4f origin = Eigen::Vector4f::Zero();
  Eigen::Quaternionf orientation = Eigen::Quaternionf::Identity();
  try {
    if (ext == ".pcd") {
      // Our own parser rather than PCL's PCDReader, which trusts its header (core/io/pcd_reader.h).
      PcdCloud pcd = parsePcd(readFileBytes(path), path);
      blob = std::move(pcd.blob);
      origin = pcd.origin;
      orientation = pcd.orientation;
    } else {
      requireSupportedPlyHeader(path);
      int version = 0;
      if (pcl::PLYReader().read(path, blob, origin, orientation, version) < 0) {
        throw Error(ErrorCode::kInvalidInput, path + ": malformed PLY file (header or data cannot be parsed)");
      }
    }
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    // PCL's readers throw PCLException but also std::out_of_range and friends on malformed
    // headers (found by tests/fuzz): all of them mean the file is bad, none is our bug.
    throw Error(ErrorCode::kInvalidInput, path + ": malformed " + ext.substr(1) + " file: " + e.what());
  }
  return sceneFromBlob(blob, origin, orientation, path);
}

void savePcd(const Scene& scene, const std::string& path) {
  requireConsistentPixels(scene, path);
  if (scene.has_color) {
    writePcd<pcl::PointXYZRGB>(scene, path);
  } else {
    writePcd<pcl::PointXYZ>(scene, path);
  }
}

void savePlyPoints(const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3i>& colors,
                   const std::string& path, PlyEncoding encoding) {
  if (!colors.empty() && colors.size() != points.size()) {
    throw Error(ErrorCode::kInvalidInput, path + ": " + std::to_string(colors.size()) + " colours for " +
                                              std::to_string(points.size()) + " points");
  }
  const bool with_color = !colors.empty();
  std::string out = "ply\nformat ";
  out += encoding == PlyEncoding::kAscii ? "ascii" : "binary_little_endian";
  out += " 1.0\nelement vertex " + std::to_string(points.size()) +
         "\nproperty float x\nproperty float y\nproperty float z\n";
  if (with_color) out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  out += "end_header\n";
  const auto channel = [](int v) { return static_cast<uint8_t>(std::clamp(v, 0, 255)); };
  char line[96];
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    if (encoding == PlyEncoding::kAscii) {
      int n = std::snprintf(line, sizeof(line), "%.9g %.9g %.9g", p.x(), p.y(), p.z());
      if (with_color) {
        n += std::snprintf(line + n, sizeof(line) - n, " %d %d %d", channel(colors[i].x()), channel(colors[i].y()),
                           channel(colors[i].z()));
      }
      out.append(line, static_cast<size_t>(n)).push_back('\n');
    } else {
      for (int c = 0; c < 3; ++c) {
        uint32_t bits;
        std::memcpy(&bits, &p[c], sizeof(bits));
        for (int byte = 0; byte < 4; ++byte) out.push_back(static_cast<char>((bits >> (8 * byte)) & 0xFFu));
      }
      if (with_color) {
        for (int c = 0; c < 3; ++c) out.push_back(static_cast<char>(channel(colors[i][c])));
      }
    }
  }
  writeFileBytes(path, out);
}

}  // namespace ism
