#include "tests/service/service_fixture.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <thread>

#include "core/io/depth_png.h"
#include "core/model/model_file.h"
#include "core/training/trainer.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "proto/wire/messages.h"
#include "tests/common/synthetic_furniture.h"

extern char** environ;

namespace ism::testing {
namespace fs = std::filesystem;

int freePort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) throw std::runtime_error("bind failed");
  socklen_t length = sizeof address;
  getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
  close(fd);
  return ntohs(address.sin_port);
}

namespace {

void writeObj(const Mesh& mesh, const fs::path& path) {
  std::ofstream out(path);
  for (const auto& v : mesh.vertices) out << "v " << v.x() << ' ' << v.y() << ' ' << v.z() << '\n';
  for (const auto& t : mesh.triangles) out << "f " << t.x() + 1 << ' ' << t.y() + 1 << ' ' << t.z() + 1 << '\n';
}

CameraIntrinsics scaledKinect(int width, int height) {
  CameraIntrinsics k;
  const float scale = width / 640.0f;
  k.width = width;
  k.height = height;
  k.fx = k.fy = 525.0f * scale;
  k.cx = (width - 1) / 2.0f;
  k.cy = (height - 1) / 2.0f;
  return k;
}

void setPose(const DepthImage& image, v1::Scene* out) {
  wire::toProto(Eigen::Vector3f(image.camera_to_world.translation()), out->mutable_sensor_origin());
  wire::toProto(Eigen::Quaternionf(image.camera_to_world.rotation()), out->mutable_sensor_orientation());
}

DepthPng toPng(const DepthImage& image, float depth_scale) {
  DepthPng png;
  png.width = image.intrinsics.width;
  png.height = image.intrinsics.height;
  for (float d : image.depth) png.pixels.push_back(static_cast<uint16_t>(std::lround(d * depth_scale)));
  return png;
}

v1::Scene depthMessage(const DepthImage& image, float depth_scale) {
  v1::Scene out;
  auto* depth = out.mutable_depth();
  depth->set_width(image.intrinsics.width);
  depth->set_height(image.intrinsics.height);
  DepthIntrinsics k;
  static_cast<PinholeIntrinsics&>(k) = image.intrinsics;
  k.depth_scale = depth_scale;
  *depth->mutable_intrinsics() = wire::intrinsicsToProto(k);
  setPose(image, &out);
  return out;
}

}  // namespace

std::string tinyModelDirectory() {
  const fs::path directory = fs::path(ISM_SERVICE_TEST_CACHE) / "models";
  const fs::path model = directory / "default.ismm";
  if (fs::exists(model)) return directory.string();
  fs::create_directories(directory);
  const fs::path meshes_dir = fs::path(ISM_SERVICE_TEST_CACHE) / "meshes";
  fs::create_directories(meshes_dir);
  std::vector<TrainingMesh> meshes;
  for (const std::string category : {"dining_chair", "dining_table"}) {
    for (int variant = 0; variant < 2; ++variant) {
      const fs::path path = meshes_dir / (category + std::to_string(variant) + ".obj");
      writeObj(syntheticFurniture(category, variant), path);
      meshes.push_back({category, path.string(), MeshPlacement{UpAxis::kZ}, "procedural"});
    }
  }
  TrainingParams params;
  params.views.views = 4;
  params.global_kmeans.k = 40;
  params.separated_kmeans.k = 20;
  params.threads = 2;
  params.command = "service tests";
  const auto start = std::chrono::steady_clock::now();
  const Model trained = train(meshes, params);
  // Save under a temporary name, then rename: parallel test processes never see half a file.
  const fs::path partial = directory / ("default.ismm.partial" + std::to_string(getpid()));
  saveModel(trained, partial.string());
  fs::rename(partial, model);
  std::cout << "trained the test model in "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() << " s\n";
  return directory.string();
}

ServerProcess::ServerProcess(const std::vector<std::string>& extra_flags,
                             std::shared_ptr<grpc::ChannelCredentials> credentials, int port,
                             const std::string& log_file)
    : credentials_(credentials ? std::move(credentials) : grpc::InsecureChannelCredentials()) {
  const std::string models = tinyModelDirectory();
  // A port picked here is free when picked, but tests run in parallel and another process may
  // bind it before this server does; the server then exits at start-up, and a fresh pick
  // starts it again. A port the test chose (a restart on its predecessor's) is taken as given.
  const bool picked = port <= 0;
  const int attempts = picked ? 4 : 1;
  for (int attempt = 1;; ++attempt) {
    port_ = picked ? freePort() : port;
    if (start(extra_flags, models, log_file)) return;
    if (attempt == attempts) throw std::runtime_error("ism-server exited during start-up");
  }
}

bool ServerProcess::start(const std::vector<std::string>& extra_flags, const std::string& models,
                          const std::string& log_file) {
  // The fixture's defaults, for the flags a test does not give itself (each may be given once).
  const auto given = [&](const std::string& flag) {
    return std::find(extra_flags.begin(), extra_flags.end(), flag) != extra_flags.end();
  };
  std::vector<std::string> args{ISM_SERVER_BINARY, "--listen", address()};
  if (!given("--threads")) args.insert(args.end(), {"--threads", "2"});
  if (!given("--log-level")) args.insert(args.end(), {"--log-level", "warn"});
  if (!given("--models")) args.insert(args.end(), {"--models", models});
  const auto metrics_flag = std::find(extra_flags.begin(), extra_flags.end(), "--metrics-listen");
  if (metrics_flag == extra_flags.end()) {
    metrics_port_ = freePort();
    args.insert(args.end(), {"--metrics-listen", "127.0.0.1:" + std::to_string(metrics_port_)});
  } else if (metrics_flag + 1 != extra_flags.end()) {  // metrics() reads the port the test chose
    const std::string& listen = *(metrics_flag + 1);
    metrics_port_ = listen.empty() ? 0 : std::atoi(listen.substr(listen.rfind(':') + 1).c_str());
  }
  args.insert(args.end(), extra_flags.begin(), extra_flags.end());
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (!log_file.empty()) {
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  }
  const int spawned = posix_spawn(&pid_, ISM_SERVER_BINARY, &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) throw std::runtime_error(std::string("cannot start ") + ISM_SERVER_BINARY);
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (std::chrono::steady_clock::now() < give_up) {
    // A fresh channel per attempt: one that first tried before the server listened keeps
    // failing its handshakes for seconds (gRPC 1.51).
    auto health = grpc::health::v1::Health::NewStub(channel());
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(500));
    grpc::health::v1::HealthCheckResponse response;
    if (health->Check(&context, {}, &response).ok() &&
        response.status() == grpc::health::v1::HealthCheckResponse::SERVING) {
      return true;
    }
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  throw std::runtime_error("ism-server did not become healthy within 30 s");
}

ServerProcess::~ServerProcess() { kill(); }

void ServerProcess::kill() {
  if (pid_ > 0) {
    ::kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
}

std::shared_ptr<grpc::Channel> ServerProcess::channel(
    const std::shared_ptr<grpc::ChannelCredentials>& credentials) const {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(64 * 1024 * 1024);
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  return grpc::CreateCustomChannel(address(), credentials, args);
}

int ServerProcess::terminate(std::chrono::seconds timeout) {
  ::kill(pid_, SIGTERM);
  const auto give_up = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < give_up) {
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return -1;
}

std::string ServerProcess::metrics() const {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(metrics_port_));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    close(fd);
    throw std::runtime_error("cannot connect to the metrics port");
  }
  const std::string request = "GET /metrics HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n";
  if (write(fd, request.data(), request.size()) != static_cast<ssize_t>(request.size())) {
    close(fd);
    throw std::runtime_error("cannot send the metrics request");
  }
  std::string response;
  char buffer[4096];
  for (ssize_t n; (n = read(fd, buffer, sizeof buffer)) > 0;) response.append(buffer, static_cast<size_t>(n));
  close(fd);
  return response;
}

SyntheticScene smallScene(int frame, int width, int height) {
  std::vector<SceneObject> objects;
  objects.push_back({"dining_table", syntheticFurniture("dining_table", 0), 0.0f, 0.3f, 0.2f});
  objects.push_back({"dining_chair", syntheticFurniture("dining_chair", 1), 0.9f, -0.2f, -0.5f});
  SyntheticSceneParams params;
  params.floor_size = 4.0f;
  params.intrinsics = scaledKinect(width, height);
  params.camera_eye = {0.05f * static_cast<float>(frame % 7), -2.8f, 1.3f};
  params.noise.seed = static_cast<uint32_t>(frame + 1);
  return composeScene(objects, params);
}

v1::Scene cloudMessage(const Scene& scene) {
  v1::Scene out;
  std::string* xyz = out.mutable_cloud()->mutable_xyz();
  xyz->resize(scene.cloud->size() * 12);
  for (size_t i = 0; i < scene.cloud->size(); ++i) {
    const auto& p = (*scene.cloud)[i];
    const float v[3] = {p.x, p.y, p.z};
    std::memcpy(xyz->data() + i * 12, v, 12);
  }
  wire::toProto(scene.sensor_origin, out.mutable_sensor_origin());
  return out;
}

v1::Scene rawDepthMessage(const DepthImage& image, float depth_scale) {
  v1::Scene out = depthMessage(image, depth_scale);
  out.mutable_depth()->set_encoding(v1::DEPTH_ENCODING_RAW_UINT16_LE);
  const DepthPng png = toPng(image, depth_scale);
  out.mutable_depth()->set_data(std::string(reinterpret_cast<const char*>(png.pixels.data()), png.pixels.size() * 2));
  return out;
}

v1::Scene pngDepthMessage(const DepthImage& image, float depth_scale) {
  v1::Scene out = depthMessage(image, depth_scale);
  out.mutable_depth()->set_encoding(v1::DEPTH_ENCODING_PNG);
  out.mutable_depth()->set_data(encodeDepthPng16(toPng(image, depth_scale)));
  return out;
}

std::string runCommand(const std::string& command, int* exit_code) {
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) throw std::runtime_error("cannot run " + command);
  std::string output;
  char buffer[4096];
  for (size_t n; (n = fread(buffer, 1, sizeof buffer, pipe)) > 0;) output.append(buffer, n);
  const int status = pclose(pipe);
  *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return output;
}

}  // namespace ism::testing
