#include "core/scanner/mesh.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <unordered_map>

#include "core/common/error.h"

namespace ism {
namespace {

[[noreturn]] void fail(const std::string& path, int line, const std::string& problem) {
  throw Error(ErrorCode::kInvalidInput,
              "mesh " + path + (line > 0 ? " line " + std::to_string(line) : "") + ": " + problem);
}

std::ifstream openMeshFile(const std::string& path, std::ios::openmode mode) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw Error(ErrorCode::kNotFound, "mesh file " + path + " does not exist");
  }
  std::ifstream in(path, mode);
  if (!in) throw Error(ErrorCode::kIo, "mesh file " + path + " cannot be opened");
  return in;
}

// Fan triangulation: exact for the convex polygons CAD exporters write.
void addPolygon(Mesh& mesh, const std::vector<int>& corners) {
  for (size_t i = 1; i + 1 < corners.size(); ++i) {
    mesh.triangles.emplace_back(corners[0], corners[i], corners[i + 1]);
  }
}

Mesh checkedResult(Mesh mesh, const std::string& path) {
  if (mesh.triangles.empty()) fail(path, 0, "no faces (" + std::to_string(mesh.vertices.size()) + " vertices)");
  for (const auto& v : mesh.vertices) {
    if (!v.allFinite()) fail(path, 0, "a vertex coordinate is NaN or infinite");
  }
  return mesh;
}

const char* skipSpace(const char* p) {
  while (*p != '\0' && std::isspace(static_cast<unsigned char>(*p))) ++p;
  return p;
}

// Parses `count` floats from p; false when fewer are there.
bool parseFloats(const char* p, int count, float* out) {
  for (int i = 0; i < count; ++i) {
    char* end = nullptr;
    out[i] = std::strtof(p, &end);
    if (end == p) return false;
    p = end;
  }
  return true;
}

Mesh loadObj(const std::string& path) {
  std::ifstream in = openMeshFile(path, std::ios::in);
  Mesh mesh;
  std::string line;
  std::vector<int> polygon;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const char* p = skipSpace(line.c_str());
    if (p[0] == 'v' && std::isspace(static_cast<unsigned char>(p[1]))) {
      float xyz[3];
      if (!parseFloats(p + 1, 3, xyz)) fail(path, line_no, "vertex needs three numbers: '" + line + "'");
      mesh.vertices.emplace_back(xyz[0], xyz[1], xyz[2]);
    } else if (p[0] == 'f' && std::isspace(static_cast<unsigned char>(p[1]))) {
      polygon.clear();
      for (p = skipSpace(p + 1); *p != '\0' && *p != '#'; p = skipSpace(p)) {
        // A corner is v, v/vt, v//vn or v/vt/vn; only v matters for depth.
        char* end = nullptr;
        const long index = std::strtol(p, &end, 10);
        const long count = static_cast<long>(mesh.vertices.size());
        const long resolved = index > 0 ? index - 1 : count + index;  // negative = relative to the end
        if (end == p || index == 0 || resolved < 0 || resolved >= count) {
          fail(path, line_no,
               "face corner '" + std::string(p, std::strcspn(p, " \t\r")) + "' is not one of the " +
                   std::to_string(count) + " vertices defined so far");
        }
        polygon.push_back(static_cast<int>(resolved));
        p = end + std::strcspn(end, " \t\r");
      }
      // Exporters write edges as two-corner faces (Sweet Home 3D's office chairs do); they
      // have no area, so a depth sensor never sees them.
      if (polygon.size() >= 3) addPolygon(mesh, polygon);
    }
  }
  if (in.bad()) throw Error(ErrorCode::kIo, "mesh file " + path + ": read error after line " + std::to_string(line_no));
  return checkedResult(std::move(mesh), path);
}

// OFF: header "OFF" (or COFF/NOFF..., whose extra per-vertex numbers are ignored), counts,
// one vertex per line, then faces "n i0 ... in-1 [colour]". '#' starts a comment.
Mesh loadOff(const std::string& path) {
  std::ifstream in = openMeshFile(path, std::ios::in);
  int line_no = 0;
  std::string line;
  auto next_line = [&](const char* expected) -> std::istringstream {
    while (std::getline(in, line)) {
      ++line_no;
      line = line.substr(0, line.find('#'));
      if (line.find_first_not_of(" \t\r") != std::string::npos) return std::istringstream(line);
    }
    fail(path, line_no, std::string("file ends where ") + expected + " was expected");
  };
  std::istringstream header = next_line("the OFF header");
  std::string magic;
  header >> magic;
  if (magic.size() < 3 || magic.compare(magic.size() - 3, 3, "OFF") != 0 || magic.find('4') != std::string::npos) {
    fail(path, line_no, "not an OFF file (header '" + magic + "')");
  }
  long num_vertices = -1, num_faces = -1;
  if (!(header >> num_vertices)) {  // counts may share the header line or follow it
    header = next_line("the vertex and face counts");
    header >> num_vertices;
  }
  if (!(header >> num_faces) || num_vertices < 0 || num_faces < 0) {
    fail(path, line_no, "expected vertex and face counts, got '" + line + "'");
  }
  Mesh mesh;
  mesh.vertices.reserve(num_vertices);
  for (long i = 0; i < num_vertices; ++i) {
    std::istringstream fields = next_line("a vertex");
    Eigen::Vector3f v;
    if (!(fields >> v.x() >> v.y() >> v.z())) fail(path, line_no, "vertex needs three numbers: '" + line + "'");
    mesh.vertices.push_back(v);
  }
  std::vector<int> polygon;
  for (long i = 0; i < num_faces; ++i) {
    std::istringstream fields = next_line("a face");
    long corners = 0;
    fields >> corners;
    if (corners < 3 || corners > num_vertices) fail(path, line_no, "face corner count out of range: '" + line + "'");
    polygon.assign(corners, 0);
    for (int& index : polygon) {
      if (!(fields >> index) || index < 0 || index >= num_vertices) {
        fail(path, line_no, "face refers to a vertex outside 0.." + std::to_string(num_vertices - 1) + ": '" + line + "'");
      }
    }
    addPolygon(mesh, polygon);
  }
  return checkedResult(std::move(mesh), path);
}

// PLY, ascii or binary of either byte order: element "vertex" (x, y, z of any scalar type)
// and element "face" (list vertex_indices or vertex_index); other elements are skipped.
enum class PlyFormat { kAscii, kBinaryLittle, kBinaryBig };

struct PlyProperty {
  std::string name;
  int size = 0;  // bytes of the value type
  char kind = 'f';  // 'i' signed, 'u' unsigned, 'f' floating
  bool is_list = false;
  int count_size = 0;
  char count_kind = 'u';
};

struct PlyElement {
  std::string name;
  long count = 0;
  std::vector<PlyProperty> properties;
};

bool plyType(const std::string& name, int* size, char* kind) {
  static const struct { const char* name; int size; char kind; } kTypes[] = {
      {"char", 1, 'i'},   {"int8", 1, 'i'},    {"uchar", 1, 'u'},  {"uint8", 1, 'u'},   {"short", 2, 'i'},
      {"int16", 2, 'i'},  {"ushort", 2, 'u'},  {"uint16", 2, 'u'}, {"int", 4, 'i'},     {"int32", 4, 'i'},
      {"uint", 4, 'u'},   {"uint32", 4, 'u'},  {"float", 4, 'f'},  {"float32", 4, 'f'}, {"double", 8, 'f'},
      {"float64", 8, 'f'}};
  for (const auto& t : kTypes) {
    if (name == t.name) {
      *size = t.size;
      *kind = t.kind;
      return true;
    }
  }
  return false;
}

class PlyValueReader {
 public:
  PlyValueReader(std::istream& in, PlyFormat format, const std::string& path) : in_(in), format_(format), path_(path) {
    const uint16_t probe = 1;
    uint8_t first;
    std::memcpy(&first, &probe, 1);
    swap_ = (format == PlyFormat::kBinaryLittle) != (first == 1);
  }

  // `element` and `index` only name the place in an error.
  double read(int size, char kind, const PlyElement& element, long index) {
    if (format_ == PlyFormat::kAscii) {
      double value;
      if (!(in_ >> value)) fail(path_, 0, where(element, index) + ": expected a number");
      return value;
    }
    uint8_t bytes[8];
    if (!in_.read(reinterpret_cast<char*>(bytes), size)) fail(path_, 0, where(element, index) + ": file is truncated");
    if (swap_) std::reverse(bytes, bytes + size);
    return decode(bytes, size, kind);
  }

 private:
  static std::string where(const PlyElement& element, long index) {
    return "element " + element.name + " " + std::to_string(index);
  }
  static double decode(const uint8_t* b, int size, char kind) {
    switch (kind * 16 + size) {
      case 'i' * 16 + 1: return static_cast<int8_t>(b[0]);
      case 'u' * 16 + 1: return b[0];
      case 'i' * 16 + 2: return as<int16_t>(b);
      case 'u' * 16 + 2: return as<uint16_t>(b);
      case 'i' * 16 + 4: return as<int32_t>(b);
      case 'u' * 16 + 4: return as<uint32_t>(b);
      case 'f' * 16 + 4: return as<float>(b);
      default: return as<double>(b);
    }
  }
  template <typename T>
  static double as(const uint8_t* b) {
    T value;
    std::memcpy(&value, b, sizeof(T));
    return static_cast<double>(value);
  }

  std::istream& in_;
  PlyFormat format_;
  const std::string& path_;
  bool swap_ = false;
};

Mesh loadPly(const std::string& path) {
  std::ifstream in = openMeshFile(path, std::ios::in | std::ios::binary);
  std::string line;
  int line_no = 0;
  auto header_line = [&]() {
    if (!std::getline(in, line)) fail(path, line_no, "header has no end_header line");
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return std::istringstream(line);
  };
  if (header_line().str() != "ply") fail(path, 1, "not a PLY file (first line is not 'ply')");
  PlyFormat format = PlyFormat::kAscii;
  std::vector<PlyElement> elements;
  for (;;) {
    std::istringstream fields = header_line();
    std::string keyword;
    fields >> keyword;
    if (keyword == "end_header") break;
    if (keyword == "format") {
      std::string name;
      fields >> name;
      if (name == "ascii") format = PlyFormat::kAscii;
      else if (name == "binary_little_endian") format = PlyFormat::kBinaryLittle;
      else if (name == "binary_big_endian") format = PlyFormat::kBinaryBig;
      else fail(path, line_no, "unknown format '" + name + "'");
    } else if (keyword == "element") {
      PlyElement element;
      if (!(fields >> element.name >> element.count) || element.count < 0) fail(path, line_no, "bad element line '" + line + "'");
      elements.push_back(element);
    } else if (keyword == "property") {
      if (elements.empty()) fail(path, line_no, "property before any element");
      PlyProperty property;
      std::string type;
      fields >> type;
      if (type == "list") {
        std::string count_type;
        property.is_list = true;
        fields >> count_type >> type;
        if (!plyType(count_type, &property.count_size, &property.count_kind)) fail(path, line_no, "unknown type '" + count_type + "'");
      }
      if (!plyType(type, &property.size, &property.kind)) fail(path, line_no, "unknown type '" + type + "'");
      fields >> property.name;
      elements.back().properties.push_back(property);
    }  // comment, obj_info: nothing to do
  }

  Mesh mesh;
  PlyValueReader reader(in, format, path);
  std::vector<int> polygon;
  for (const PlyElement& element : elements) {
    const bool is_vertex = element.name == "vertex";
    const bool is_face = element.name == "face";
    int axis[3] = {-1, -1, -1};
    for (size_t p = 0; p < element.properties.size(); ++p) {
      const std::string& name = element.properties[p].name;
      if (is_vertex && name.size() == 1 && name[0] >= 'x' && name[0] <= 'z') axis[name[0] - 'x'] = static_cast<int>(p);
    }
    if (is_vertex && (axis[0] < 0 || axis[1] < 0 || axis[2] < 0)) fail(path, 0, "element vertex lacks x, y or z");
    for (long i = 0; i < element.count; ++i) {
      Eigen::Vector3f xyz = Eigen::Vector3f::Zero();
      for (size_t p = 0; p < element.properties.size(); ++p) {
        const PlyProperty& property = element.properties[p];
        if (!property.is_list) {
          const double value = reader.read(property.size, property.kind, element, i);
          for (int a = 0; a < 3; ++a) {
            if (axis[a] == static_cast<int>(p)) xyz[a] = static_cast<float>(value);
          }
          continue;
        }
        const double count = reader.read(property.count_size, property.count_kind, element, i);
        if (count < 0 || count > 1e6) fail(path, 0, "element " + element.name + " " + std::to_string(i) + ": list length " + std::to_string(count));
        const bool corners = is_face && (property.name == "vertex_indices" || property.name == "vertex_index");
        polygon.clear();
        for (long k = 0; k < static_cast<long>(count); ++k) {
          const double value = reader.read(property.size, property.kind, element, i);
          if (corners) polygon.push_back(static_cast<int>(value));
        }
        if (!corners) continue;
        if (polygon.size() >= 3) addPolygon(mesh, polygon);  // edges have no area (see the OBJ reader)
      }
      if (is_vertex) mesh.vertices.push_back(xyz);
    }
  }
  const int num_vertices = static_cast<int>(mesh.vertices.size());
  for (const auto& t : mesh.triangles) {
    if (t.minCoeff() < 0 || t.maxCoeff() >= num_vertices) {
      fail(path, 0, "a face refers to a vertex outside 0.." + std::to_string(num_vertices - 1));
    }
  }
  return checkedResult(std::move(mesh), path);
}

}  // namespace

Eigen::AlignedBox3f Mesh::bounds() const {
  Eigen::AlignedBox3f box;
  for (const auto& v : vertices) box.extend(v);
  return box;
}

Mesh loadMesh(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".obj") return loadObj(path);
  if (extension == ".off") return loadOff(path);
  if (extension == ".ply") return loadPly(path);
  throw Error(ErrorCode::kInvalidInput, "mesh " + path + ": unknown extension '" + extension + "' (expected .obj, .off or .ply)");
}

Mesh placeMesh(const Mesh& mesh, const MeshPlacement& placement) {
  if (mesh.vertices.empty()) throw Error(ErrorCode::kInvalidInput, "placeMesh: the mesh has no vertices");
  if ((placement.size.array() < 0).any() || !placement.size.allFinite()) {
    throw Error(ErrorCode::kInvalidInput, "placeMesh: size must be >= 0, got (" + std::to_string(placement.size.x()) +
                                              ", " + std::to_string(placement.size.y()) + ", " +
                                              std::to_string(placement.size.z()) + ")");
  }
  // Y-up to Z-up is +90 deg about x: the model's front (+z in Y-up formats) faces -y.
  Eigen::Matrix3f up_change = Eigen::Matrix3f::Identity();
  if (placement.up == UpAxis::kY) up_change << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  const Eigen::Matrix3f rotation = up_change * placement.pre_rotation;

  Mesh placed = mesh;
  for (auto& v : placed.vertices) v = rotation * v;
  const Eigen::AlignedBox3f box = placed.bounds();
  const Eigen::Vector3f extent = box.sizes();

  Eigen::Vector3f scale = Eigen::Vector3f::Ones();
  const auto ratio = [&](int axis) {
    if (extent[axis] <= 0) {
      throw Error(ErrorCode::kInvalidInput, "placeMesh: the mesh is flat along axis " + std::to_string(axis) +
                                                " and cannot be scaled to " + std::to_string(placement.size[axis]) + " m");
    }
    return placement.size[axis] / extent[axis];
  };
  if (placement.uniform && (placement.size.array() > 0).all()) {
    for (int a = 0; a < 3; ++a) ratio(a);  // throws for a flat mesh
    const float mesh_long = std::max(extent.x(), extent.y()), mesh_short = std::min(extent.x(), extent.y());
    const float size_long = std::max(placement.size.x(), placement.size.y());
    const float size_short = std::min(placement.size.x(), placement.size.y());
    scale.setConstant(std::cbrt(size_long / mesh_long * (size_short / mesh_short) * ratio(2)));
  } else if (placement.uniform) {
    int axis = 2;  // the height decides; else the first given extent
    while (axis >= 0 && placement.size[axis] == 0) --axis;
    if (axis >= 0) scale.setConstant(ratio(axis));
  } else if ((placement.size.array() > 0).any()) {
    float given_sum = 0;
    int given = 0;
    for (int a = 0; a < 3; ++a) {
      if (placement.size[a] > 0) {
        scale[a] = ratio(a);
        given_sum += scale[a];
        ++given;
      }
    }
    for (int a = 0; a < 3; ++a) {
      if (placement.size[a] == 0) scale[a] = given_sum / given;
    }
  }
  const Eigen::Vector3f anchor(box.center().x(), box.center().y(), box.min().z());
  for (auto& v : placed.vertices) v = (v - anchor).cwiseProduct(scale);
  return placed;
}

Mesh transformed(const Mesh& mesh, const Eigen::Isometry3f& pose) {
  Mesh out = mesh;
  for (auto& v : out.vertices) v = pose * v;
  return out;
}

std::vector<Eigen::Vector3f> sampleSurface(const Mesh& mesh, float spacing, size_t max_points, uint32_t seed) {
  if (!(spacing > 0)) throw Error(ErrorCode::kInvalidInput, "sampleSurface: spacing must be > 0");
  std::vector<double> cumulative;  // triangle areas, summed
  cumulative.reserve(mesh.triangles.size());
  double total = 0;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3f& a = mesh.vertices[static_cast<size_t>(t.x())];
    total += 0.5 * static_cast<double>((mesh.vertices[static_cast<size_t>(t.y())] - a)
                                           .cross(mesh.vertices[static_cast<size_t>(t.z())] - a)
                                           .norm());
    cumulative.push_back(total);
  }
  if (!(total > 0)) return {};
  // Four candidates per cube on average over the area, so that thinning leaves few holes.
  const auto candidates = static_cast<size_t>(std::min(4.0 * total / (spacing * spacing), 4e6));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> area(0.0, total);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::unordered_map<uint64_t, Eigen::Vector3f> cells;
  for (size_t i = 0; i < candidates; ++i) {
    const size_t k = static_cast<size_t>(std::lower_bound(cumulative.begin(), cumulative.end(), area(rng)) - cumulative.begin());
    const Eigen::Vector3i& t = mesh.triangles[std::min(k, mesh.triangles.size() - 1)];
    float r1 = unit(rng), r2 = unit(rng);
    if (r1 + r2 > 1) {
      r1 = 1 - r1;
      r2 = 1 - r2;
    }
    const Eigen::Vector3f& a = mesh.vertices[static_cast<size_t>(t.x())];
    const Eigen::Vector3f p = a + r1 * (mesh.vertices[static_cast<size_t>(t.y())] - a) +
                              r2 * (mesh.vertices[static_cast<size_t>(t.z())] - a);
    const Eigen::Vector3i cell = (p / spacing).array().floor().cast<int>();
    const uint64_t key = (static_cast<uint64_t>(static_cast<uint32_t>(cell.x()) & 0x1fffff) << 42) |
                         (static_cast<uint64_t>(static_cast<uint32_t>(cell.y()) & 0x1fffff) << 21) |
                         (static_cast<uint64_t>(static_cast<uint32_t>(cell.z()) & 0x1fffff));
    cells.emplace(key, p);
  }
  std::vector<std::pair<uint64_t, Eigen::Vector3f>> sorted(cells.begin(), cells.end());
  std::sort(sorted.begin(), sorted.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<Eigen::Vector3f> points;
  points.reserve(sorted.size());
  for (const auto& c : sorted) points.push_back(c.second);
  std::shuffle(points.begin(), points.end(), rng);
  if (points.size() > max_points) points.resize(max_points);
  return points;
}

}  // namespace ism
