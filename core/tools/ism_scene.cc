// ism-scene: a synthetic Kinect frame of CAD meshes standing on a floor, with exact ground
// truth. Writes NAME.pcd (world frame, z up, viewpoint = camera), NAME_depth.png (1000 units
// per metre) and NAME.json in the format of the real development scenes.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/common/error.h"
#include "core/io/cloud_io.h"
#include "core/scanner/scanner.h"

namespace {

using ism::Error;
using ism::ErrorCode;
using nlohmann::json;
using nlohmann::ordered_json;

constexpr float kDepthUnitsPerMetre = 1000.0f;

struct ObjectSpec {
  std::string category;
  std::string mesh_path;
  ism::MeshPlacement placement;
  float x = 0, y = 0, yaw = 0;
};

struct SceneSpec {
  std::vector<ObjectSpec> objects;
  ism::SyntheticSceneParams params;
  std::string source = "synthetic: ism-scene virtual Kinect render of CAD meshes";
  std::string license = "that of the meshes";
};

// "a,b,c" -> exactly `count` numbers; `what` names the option for the error.
std::vector<float> parseNumbers(const std::string& text, size_t count, const std::string& what) {
  std::vector<float> numbers;
  std::stringstream fields(text);
  std::string field;
  while (std::getline(fields, field, ',')) {
    size_t used = 0;
    float value = 0;
    try {
      value = std::stof(field, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != field.size() || !std::isfinite(value)) {
      throw Error(ErrorCode::kInvalidInput, what + ": '" + field + "' in '" + text + "' is not a number");
    }
    numbers.push_back(value);
  }
  if (numbers.size() != count) {
    throw Error(ErrorCode::kInvalidInput, what + ": expected " + std::to_string(count) + " comma-separated numbers, got '" +
                                              text + "'");
  }
  return numbers;
}

ism::UpAxis parseUp(const std::string& up, const std::string& what) {
  if (up == "y") return ism::UpAxis::kY;
  if (up == "z") return ism::UpAxis::kZ;
  throw Error(ErrorCode::kInvalidInput, what + ": up axis must be 'y' or 'z', got '" + up + "'");
}

// CATEGORY:MESH:W,D,H:X,Y,YAW; MESH may itself contain ':'.
ObjectSpec parseObjectOption(const std::string& text, ism::UpAxis up) {
  const size_t first = text.find(':');
  const size_t last = text.rfind(':');
  const size_t second_last = last == std::string::npos || last == 0 ? std::string::npos : text.rfind(':', last - 1);
  if (first == std::string::npos || second_last == std::string::npos || second_last <= first) {
    throw Error(ErrorCode::kInvalidInput, "--object '" + text + "': expected CATEGORY:MESH:W,D,H:X,Y,YAW");
  }
  ObjectSpec object;
  object.category = text.substr(0, first);
  object.mesh_path = text.substr(first + 1, second_last - first - 1);
  if (object.category.empty() || object.mesh_path.empty()) {
    throw Error(ErrorCode::kInvalidInput, "--object '" + text + "': empty category or mesh path");
  }
  const auto size = parseNumbers(text.substr(second_last + 1, last - second_last - 1), 3, "--object " + text + " size");
  const auto pose = parseNumbers(text.substr(last + 1), 3, "--object " + text + " position");
  object.placement.up = up;
  object.placement.size = {size[0], size[1], size[2]};
  object.x = pose[0];
  object.y = pose[1];
  object.yaw = pose[2];
  return object;
}

Eigen::Vector3f vector3(const json& value, const std::string& what) {
  if (!value.is_array() || value.size() != 3) throw Error(ErrorCode::kInvalidInput, what + " must be an array of 3 numbers");
  return {value[0].get<float>(), value[1].get<float>(), value[2].get<float>()};
}

SceneSpec readSpec(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(ErrorCode::kNotFound, "scene spec " + path + " cannot be opened");
  SceneSpec spec;
  const std::filesystem::path base = std::filesystem::path(path).parent_path();
  std::string where = "scene spec " + path;  // narrowed while parsing, so errors name the field
  try {
    const json root = json::parse(in);
    spec.source = root.value("source", spec.source);
    spec.license = root.value("license", spec.license);
    spec.params.noise.seed = root.value("seed", spec.params.noise.seed);
    spec.params.noise.enabled = root.value("noise", spec.params.noise.enabled);
    spec.params.floor_size = root.value("floor_size", spec.params.floor_size);
    if (root.contains("camera")) {
      where = "scene spec " + path + ": camera";
      spec.params.camera_eye = vector3(root["camera"].at("eye"), where + ".eye");
      spec.params.camera_target = vector3(root["camera"].at("target"), where + ".target");
    }
    where = "scene spec " + path;
    const json& objects = root.at("objects");
    for (size_t i = 0; i < objects.size(); ++i) {
      const json& o = objects[i];
      where = "scene spec " + path + ": objects[" + std::to_string(i) + "]";
      ObjectSpec object;
      object.category = o.at("category").get<std::string>();
      const std::filesystem::path mesh = o.at("mesh").get<std::string>();
      object.mesh_path = (mesh.is_relative() ? base / mesh : mesh).string();  // relative to the spec
      object.placement.up = parseUp(o.value("up", std::string("y")), where);
      object.placement.uniform = o.value("uniform", false);
      if (o.contains("size")) object.placement.size = vector3(o["size"], where + ".size");
      if (o.contains("rotation")) {  // Sweet Home 3D modelRotation, row-major 3x3
        const auto r = o["rotation"].get<std::vector<float>>();
        if (r.size() != 9) throw Error(ErrorCode::kInvalidInput, where + ".rotation must have 9 numbers");
        object.placement.pre_rotation = Eigen::Map<const Eigen::Matrix<float, 3, 3, Eigen::RowMajor>>(r.data());
      }
      object.x = o.value("x", 0.0f);
      object.y = o.value("y", 0.0f);
      object.yaw = o.value("yaw", 0.0f);
      spec.objects.push_back(object);
    }
  } catch (const json::exception& e) {
    throw Error(ErrorCode::kInvalidInput, where + ": " + e.what());
  }
  return spec;
}

// Micrometres are far below the sensor's resolution; fewer digits keep the file readable.
double rounded(float v) { return std::round(static_cast<double>(v) * 1e6) / 1e6; }
ordered_json toJson(const Eigen::Vector3f& v) { return ordered_json::array({rounded(v.x()), rounded(v.y()), rounded(v.z())}); }

ordered_json groundTruth(const std::string& name, const SceneSpec& spec, const ism::SyntheticScene& scene) {
  const ism::CameraIntrinsics& k = scene.depth.intrinsics;
  ordered_json pose = ordered_json::array();
  const Eigen::Matrix4f m = scene.depth.camera_to_world.matrix();
  for (int r = 0; r < 4; ++r) pose.push_back({rounded(m(r, 0)), rounded(m(r, 1)), rounded(m(r, 2)), rounded(m(r, 3))});
  ordered_json out = {
      {"scene", name},
      {"cloud", name + ".pcd"},
      {"depth", name + "_depth.png"},
      {"sensor", "virtual kinect"},
      {"frame", "world, z up"},
      {"boxes", "center = bounding-box centre; size = extents along the object's axes (width, depth, height); "
                "yaw = rotation about +z"},
      {"intrinsics", {{"width", k.width}, {"height", k.height}, {"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy},
                      {"depth_scale", kDepthUnitsPerMetre}}},
      {"camera_frame", "optical: x right, y down, z forward"},
      {"camera_to_world", pose},
      {"noise", {{"enabled", spec.params.noise.enabled}, {"seed", spec.params.noise.seed}}},
      {"source", spec.source},
      {"license", spec.license},
      {"objects", ordered_json::array()},
  };
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    const ism::GroundTruthObject& o = scene.objects[i];
    out["objects"].push_back({{"category", o.category},
                              {"center", toJson(o.center)},
                              {"size", toJson(o.size)},
                              {"yaw", rounded(o.yaw)},
                              {"points", o.points},
                              {"mesh", spec.objects[i].mesh_path}});
  }
  return out;
}

void run(const std::string& out_prefix, const SceneSpec& spec) {
  if (spec.objects.empty()) throw Error(ErrorCode::kInvalidInput, "no objects: give --object or a --spec with objects");
  const std::filesystem::path prefix(out_prefix);
  const std::string name = prefix.filename().string();
  if (name.empty()) throw Error(ErrorCode::kInvalidInput, "--out '" + out_prefix + "' must end in a scene name (DIR/NAME)");
  if (prefix.has_parent_path()) std::filesystem::create_directories(prefix.parent_path());

  std::vector<ism::SceneObject> objects;
  for (const ObjectSpec& spec_object : spec.objects) {
    objects.push_back({spec_object.category, ism::placeMesh(ism::loadMesh(spec_object.mesh_path), spec_object.placement),
                       spec_object.x, spec_object.y, spec_object.yaw});
  }
  const ism::SyntheticScene scene = ism::composeScene(objects, spec.params);
  ism::savePcd(scene.scene, out_prefix + ".pcd");
  ism::saveDepthPng(scene.depth, kDepthUnitsPerMetre, out_prefix + "_depth.png");
  std::ofstream json_out(out_prefix + ".json");
  json_out << groundTruth(name, spec, scene).dump(1) << "\n";
  if (!json_out) throw Error(ErrorCode::kIo, "cannot write " + out_prefix + ".json");

  std::cout << out_prefix << ": " << scene.scene.cloud->size() << " points";
  for (const auto& o : scene.objects) std::cout << ", " << o.category << " " << o.points;
  std::cout << std::endl;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Render a synthetic Kinect frame of CAD meshes on a floor, with ground truth"};
  std::string out, spec_path, up = "y", camera;
  std::vector<std::string> object_options;
  uint32_t seed = 1;
  float floor_size = ism::SyntheticSceneParams{}.floor_size;
  bool no_noise = false;
  std::string source, license;
  app.add_option("--out", out, "output prefix DIR/NAME: writes NAME.pcd, NAME_depth.png, NAME.json")->required();
  auto* spec_opt = app.add_option("--spec", spec_path, "scene JSON: objects [{category, mesh, size, x, y, yaw, up, "
                                                       "rotation, uniform}], camera {eye, target}, seed, noise, "
                                                       "floor_size, source, license");
  auto* object_opt = app.add_option("--object", object_options,
                                    "CATEGORY:MESH:W,D,H:X,Y,YAW (metres, radians; a size of 0 is derived "
                                    "from the others); repeat for several objects");
  object_opt->excludes(spec_opt);
  auto* up_opt = app.add_option("--up", up, "up axis of the --object meshes (y or z)")->capture_default_str();
  up_opt->excludes(spec_opt);
  auto* camera_opt = app.add_option("--camera", camera, "ex,ey,ez,tx,ty,tz: camera eye and the point it looks at");
  auto* seed_opt = app.add_option("--seed", seed, "noise seed")->capture_default_str();
  auto* floor_opt =
      app.add_option("--floor", floor_size, "floor square side in metres (0 = no floor)")->capture_default_str();
  auto* source_opt = app.add_option("--source", source, "ground truth 'source' text (credit the meshes)");
  auto* license_opt = app.add_option("--license", license, "ground truth 'license' text");
  app.add_flag("--no-noise", no_noise, "exact depth (range limits still apply)");
  CLI11_PARSE(app, argc, argv);

  try {
    SceneSpec spec;
    if (!spec_path.empty()) spec = readSpec(spec_path);
    for (const std::string& text : object_options) spec.objects.push_back(parseObjectOption(text, parseUp(up, "--up")));
    // Options given on the command line override the spec.
    if (*camera_opt) {
      const auto c = parseNumbers(camera, 6, "--camera");
      spec.params.camera_eye = {c[0], c[1], c[2]};
      spec.params.camera_target = {c[3], c[4], c[5]};
    }
    if (*seed_opt) spec.params.noise.seed = seed;
    if (*floor_opt) spec.params.floor_size = floor_size;
    if (*source_opt) spec.source = source;
    if (*license_opt) spec.license = license;
    if (no_noise) spec.params.noise.enabled = false;
    run(out, spec);
  } catch (const Error& e) {
    std::cerr << "ism-scene: " << ism::errorCodeName(e.code()) << ": " << e.what() << std::endl;
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "ism-scene: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
