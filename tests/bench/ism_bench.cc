// ism-bench: where the time of one frame goes, in process and over gRPC, and what the server
// costs in memory. Google Benchmark; built with the tests, never run by ctest (tests/bench/run.sh
// runs it with repetitions and prints the medians).
//
// Every benchmark goes through core's public API (the front-end free functions, Codebook,
// HoughSpace, recognize()) or the real ism-server binary, so it measures whatever the code does
// when it runs. Stage benchmarks take an OpenMP thread count as their argument: 1, and every
// processor (omp_get_num_procs()).
#include <arpa/inet.h>
#include <benchmark/benchmark.h>
#include <grpcpp/grpcpp.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "client/cli/common.h"
#include "core/common/error.h"
#include "core/frontend/frontend.h"
#include "core/gravity/gravity.h"
#include "core/gravity/viewpoint.h"
#include "core/io/cloud_io.h"
#include "core/model/model_file.h"
#include "core/recognition/recognizer.h"
#include "core/recognition/verification.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "ism/v1/service.grpc.pb.h"

extern char** environ;

namespace ism::bench {
namespace fs = std::filesystem;

void setThreads(int threads) {
#ifdef _OPENMP
  omp_set_num_threads(threads);
#else
  (void)threads;
#endif
}

int processors() {
#ifdef _OPENMP
  return omp_get_num_procs();
#else
  return 1;
#endif
}

// ---------------------------------------------------------------------------------------------
// Inputs, loaded once before any benchmark runs.

struct Config {
  std::string model_path = std::string(ISM_SOURCE_DIR) + "/models/default/furniture.ismm";
  std::string scene_path;  // empty: the development data's Kinect frame, or the sample scene without it
  std::string server_binary = ISM_SERVER_BINARY;
  int recognitions = 20;  // before the server's memory is read the second time
};

struct Inputs {
  Model model;
  Scene scene;
  RecognitionOptions options;  // the service's defaults: global codebook, trained k-NN, LW
  // Each stage's input, made once by the stage before it (with every thread).
  XyzCloud::Ptr downsampled, smoothed;
  bool organized = false;  // occluding-contour keypoints, found before the normals
  Surface::Ptr surface;
  std::vector<int> keypoints;
  Features features;
  std::vector<Activation> activations;
  std::vector<float> thresholds;  // per category, the model's for options.strategy
};

Config& config() {
  static Config c;
  return c;
}

Inputs& inputs() {
  static Inputs in;
  return in;
}

void prepareInputs() {
  Inputs& in = inputs();
  const Config& c = config();
  in.model = loadModel(c.model_path);
  in.scene = loadCloudFile(c.scene_path);
  in.options.strategy.activation = in.model.trained_knn;
  const FrontEndParams& fe = in.model.front_end;
  setThreads(processors());
  in.downsampled = downsample(*in.scene.cloud, fe.downsample);
  in.smoothed = fe.smoothing.enabled ? smooth(*in.downsampled, fe.smoothing) : in.downsampled;
  in.organized = resolveKeypointMethod(fe.keypoints, in.scene) == KeypointMethod::kOccludingContour;
  if (in.organized) {  // as extractFeatures: keypoints first, then the normals around them
    NormalEstimator normals(*in.smoothed, fe.normals, in.scene.sensor_origin);
    in.keypoints = detectContourKeypoints(in.scene, normals, fe.keypoints, fe.downsample.leaf_size);
    normals.computeNear(in.keypoints, fe.shot.radius);
    std::vector<int> index_in_surface;
    in.surface = normals.surface(&index_in_surface);
    for (int& k : in.keypoints) k = index_in_surface[static_cast<size_t>(k)];
  } else {
    in.surface = estimateNormals(*in.smoothed, fe.normals, in.scene.sensor_origin);
    in.keypoints = detectKeypoints(in.scene, *in.surface, fe.keypoints, fe.downsample.leaf_size);
  }
  // Voting and the peak search run on what the whole front end gives: the keypoints off floor and
  // walls, with the gravity stage's up, heights and upright frames.
  in.features = extractFeatures(in.scene, fe, fe.smoothing.enabled).features;
  in.activations = in.model.global_codebook->activate(in.features.descriptors, in.options.strategy.activation);
  const Strategy& s = in.options.strategy;
  for (const auto& category : in.model.categories) {
    const auto it = category.thresholds.find({s.codebook, s.activation.strategy, s.weighting});
    if (it == category.thresholds.end()) {
      throw Error(ErrorCode::kInvalidInput, "model " + c.model_path + " has no global/knn/lw threshold for '" +
                                                category.name + "'");
    }
    in.thresholds.push_back(it->second);
  }
  std::cerr << "ism-bench: " << in.scene.source << ": " << in.scene.cloud->size() << " points ("
            << in.scene.image_width << "x" << in.scene.image_height << "), " << in.smoothed->size()
            << " surface points (" << in.surface->size() << " with normals), " << in.keypoints.size() << " keypoints, " << in.features.size()
            << " described; model " << c.model_path << " (" << in.model.categories.size() << " categories)\n";
}

// ---------------------------------------------------------------------------------------------
// Per stage of one frame, on `threads` OpenMP threads.

void setCommon(benchmark::State& state) {
  setThreads(static_cast<int>(state.range(0)));
  state.counters["threads"] = static_cast<double>(state.range(0));
}

void BM_Downsample(benchmark::State& state) {
  setCommon(state);
  const Inputs& in = inputs();
  for (auto _ : state) benchmark::DoNotOptimize(downsample(*in.scene.cloud, in.model.front_end.downsample));
  state.counters["points"] = static_cast<double>(in.scene.cloud->size());
}

// The floor, walls and up by RANSAC over the downsampled points (the caller's up not given).
void BM_Gravity(benchmark::State& state) {
  setCommon(state);
  const Inputs& in = inputs();
  std::vector<Eigen::Vector3f> positions(in.smoothed->size());
  for (size_t i = 0; i < positions.size(); ++i) positions[i] = (*in.smoothed)[i].getVector3fMap();
  const Eigen::Vector3f sensor_up = in.scene.sensor_orientation * Eigen::Vector3f(0, -1, 0);
  for (auto _ : state) {
    benchmark::DoNotOptimize(estimateGravity(positions, in.scene.sensor_origin, sensor_up, in.scene.up,
                                             in.model.front_end.gravity));
  }
  state.counters["points"] = static_cast<double>(positions.size());
}

void BM_Smooth(benchmark::State& state) {
  setCommon(state);
  const Inputs& in = inputs();
  if (!in.model.front_end.smoothing.enabled) {
    state.SkipWithError("the model's front end does not smooth scenes");
    return;
  }
  for (auto _ : state) benchmark::DoNotOptimize(smooth(*in.downsampled, in.model.front_end.smoothing));
  state.counters["points"] = static_cast<double>(in.downsampled->size());
}

// Organized scenes: the normals within SHOT's radius of the keypoints, from an estimator that
// has the keypoints' (made untimed each iteration, as the keypoints stage does); otherwise every
// point's.
void BM_Normals(benchmark::State& state) {
  setCommon(state);
  const Inputs& in = inputs();
  const FrontEndParams& fe = in.model.front_end;
  size_t computed = 0;
  for (auto _ : state) {
    if (!in.organized) {
      computed = estimateNormals(*in.smoothed, fe.normals, in.scene.sensor_origin)->size();
      continue;
    }
    state.PauseTiming();
    NormalEstimator normals(*in.smoothed, fe.normals, in.scene.sensor_origin);
    const std::vector<int> keypoints = detectContourKeypoints(in.scene, normals, fe.keypoints, fe.downsample.leaf_size);
    state.ResumeTiming();
    normals.computeNear(keypoints, fe.shot.radius);
    computed = normals.surface()->size();
  }
  state.counters["points"] = static_cast<double>(in.smoothed->size());
  state.counters["with_normals"] = static_cast<double>(computed);
}

// Organized scenes: contours, the grid of the normals and the normals of the points a contour
// pixel may pick; otherwise the boundary test over every point's normal.
void BM_Keypoints(benchmark::State& state) {
  setCommon(state);
  const Inputs& in = inputs();
  const FrontEndParams& fe = in.model.front_end;
  for (auto _ : state) {
    if (in.organized) {
      NormalEstimator normals(*in.smoothed, fe.normals, in.scene.sensor_origin);
      benchmark::DoNotOptimize(detectContourKeypoints(in.scene, normals, fe.keypoints, fe.downsample.leaf_size));
    } else {
      benchmark::DoNotOptimize(detectKeypoints(in.scene, *in.surface, fe.keypoints, fe.downsample.leaf_size));
    }
  }
  state.counters["keypoints"] = static_cast<double>(in.keypoints.size());
}

void BM_Describe(benchmark::State& state) {
  setCommon(state);
  const Inputs& in = inputs();
  for (auto _ : state) benchmark::DoNotOptimize(describe(*in.surface, in.keypoints, in.model.front_end.shot));
  state.counters["described"] = static_cast<double>(in.features.size());
}

void BM_Activate(benchmark::State& state) {
  setCommon(state);
  const Inputs& in = inputs();
  for (auto _ : state) {
    benchmark::DoNotOptimize(in.model.global_codebook->activate(in.features.descriptors, in.options.strategy.activation));
  }
  state.counters["codewords"] = static_cast<double>(in.model.global_codebook->size());
}

// Every category's Hough space, as recognize() builds them (one at a time).
void BM_Vote(benchmark::State& state) {
  setCommon(state);
  const Inputs& in = inputs();
  size_t votes = 0;
  for (auto _ : state) {
    votes = 0;
    for (size_t c = 0; c < in.model.categories.size(); ++c) {
      const HoughSpace hough(in.model, static_cast<int>(c), in.features, in.activations, in.options.strategy);
      votes += hough.votes();
    }
  }
  state.counters["votes"] = static_cast<double>(votes);
}

// Peak search, support and boxes in every category's Hough space (built before timing).
void BM_Hypotheses(benchmark::State& state) {
  setCommon(state);
  const Inputs& in = inputs();
  std::vector<std::unique_ptr<HoughSpace>> spaces;
  for (size_t c = 0; c < in.model.categories.size(); ++c) {
    spaces.push_back(std::make_unique<HoughSpace>(in.model, static_cast<int>(c), in.features, in.activations,
                                                  in.options.strategy));
  }
  size_t peaks = 0;
  for (auto _ : state) {
    peaks = 0;
    for (size_t c = 0; c < spaces.size(); ++c) peaks += spaces[c]->findPeaks(in.thresholds[c]).size();
  }
  state.counters["peaks"] = static_cast<double>(peaks);
}

// The whole recognize() call; its own per-stage timings become counters (mean per call).
void BM_Recognize(benchmark::State& state) {
  setCommon(state);
  const Inputs& in = inputs();
  std::map<std::string, double> stage_ms;
  size_t hypotheses = 0;
  for (auto _ : state) {
    const RecognitionResult result = recognize(in.model, in.scene, in.options);
    for (const auto& [name, ms] : result.timings.stages) stage_ms[name] += ms;
    hypotheses = result.hypotheses.size();
  }
  for (const auto& [name, ms] : stage_ms) state.counters[name + "_ms"] = benchmark::Counter(ms, benchmark::Counter::kAvgIterations);
  state.counters["hypotheses"] = static_cast<double>(hypotheses);
}

// Verification of 10 candidates (issue 15's budget: 20 ms per frame on one core): the 10 most
// confident hypotheses recognize() finds down to confidence 0.01, their fits cleared, fitted to
// the scene again, the scene made ready for it included.
void BM_Verify10(benchmark::State& state) {
  setCommon(state);
  const Inputs& in = inputs();
  RecognitionOptions options = in.options;
  // Ten candidates: the most confident peaks, not suppressed, so that a frame with few objects
  // still gives ten (tum_desk's 3 objects give 6 hypotheses after suppression).
  options.min_confidence = 0.01f;
  options.one_answer_per_object = false;
  std::vector<Hypothesis> candidates = recognize(in.model, in.scene, options).hypotheses;
  if (candidates.size() > 10) candidates.resize(10);
  for (auto& h : candidates) h.verification.reset();
  const Scene seen = lookedAt(in.scene);
  size_t verified = 0;
  for (auto _ : state) {
    std::vector<Hypothesis> hypotheses = candidates;
    const VerificationScene view = makeVerificationScene(seen, in.features.gravity);
    verifyHypotheses(view, in.model, hypotheses);
    verified = static_cast<size_t>(std::count_if(hypotheses.begin(), hypotheses.end(),
                                                 [](const Hypothesis& h) { return h.verification.has_value(); }));
  }
  state.counters["candidates"] = static_cast<double>(candidates.size());
  state.counters["verified"] = static_cast<double>(verified);
}

void BM_ModelLoad(benchmark::State& state) {
  size_t categories = 0;
  for (auto _ : state) categories = loadModel(config().model_path).categories.size();
  state.counters["bytes"] = static_cast<double>(fs::file_size(config().model_path));
  state.counters["categories"] = static_cast<double>(categories);
}

// ---------------------------------------------------------------------------------------------
// The real ism-server on 127.0.0.1.

int freePort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) throw std::runtime_error("socket() failed");
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    close(fd);
    throw std::runtime_error("bind() to 127.0.0.1 failed");
  }
  socklen_t length = sizeof address;
  getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
  close(fd);
  return ntohs(address.sin_port);
}

class Server {
 public:
  // threads_per_request > 0: one worker running each recognition on that many OpenMP threads,
  // like the in-process benchmark it is compared with; 0: the server's defaults, as deployed.
  explicit Server(int threads_per_request) {
    const Config& c = config();
    port_ = freePort();
    std::vector<std::string> args{c.server_binary, "--listen", address(), "--models",
                                  fs::path(c.model_path).parent_path().string(), "--metrics-listen", "",
                                  "--log-level", "warn"};
    if (threads_per_request > 0) {
      args.insert(args.end(), {"--threads", "1", "--threads-per-request", std::to_string(threads_per_request)});
    }
    std::vector<std::string> env;
    for (char** e = environ; *e != nullptr; ++e) env.emplace_back(*e);
    std::vector<char*> argv, envp;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    for (auto& e : env) envp.push_back(e.data());
    envp.push_back(nullptr);
    pid_ = fork();
    if (pid_ < 0) throw std::runtime_error("fork() failed");
    if (pid_ == 0) {
      // Only async-signal-safe calls between fork and exec. The server dies with the benchmark,
      // also when that is interrupted.
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      execve(argv[0], argv.data(), envp.data());
      _exit(127);
    }
    grpc::ChannelArguments channel_args;
    channel_args.SetMaxReceiveMessageSize(64 * 1024 * 1024);
    channel_args.SetMaxSendMessageSize(64 * 1024 * 1024);
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (std::chrono::steady_clock::now() < give_up) {
      // A fresh channel per attempt: one that tried before the server listened keeps failing
      // its handshakes for a while (gRPC 1.51).
      channel_ = grpc::CreateCustomChannel(address(), grpc::InsecureChannelCredentials(), channel_args);
      auto health = grpc::health::v1::Health::NewStub(channel_);
      grpc::ClientContext context;
      context.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(500));
      grpc::health::v1::HealthCheckResponse response;
      if (health->Check(&context, {}, &response).ok() &&
          response.status() == grpc::health::v1::HealthCheckResponse::SERVING) {
        stub_ = v1::FurnitureRecognizer::NewStub(channel_);
        return;
      }
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        throw std::runtime_error(c.server_binary + " exited during start-up");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    stop();
    throw std::runtime_error(c.server_binary + " did not become healthy within 60 s");
  }
  ~Server() { stop(); }
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  pid_t pid() const { return pid_; }

  grpc::Status recognize(const v1::RecognizeRequest& request, v1::RecognizeResponse* response) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
    return stub_->Recognize(&context, request, response);
  }

  // A field of /proc/PID/status ("VmRSS", "VmHWM") in MB.
  double statusMb(const std::string& field) const {
    std::ifstream in("/proc/" + std::to_string(pid_) + "/status");
    for (std::string line; std::getline(in, line);) {
      if (line.rfind(field + ":", 0) == 0) return std::stod(line.substr(field.size() + 1)) / 1024.0;  // kB
    }
    return std::numeric_limits<double>::quiet_NaN();
  }

 private:
  void stop() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(15);
    while (std::chrono::steady_clock::now() < give_up) {
      if (waitpid(pid_, nullptr, WNOHANG) == pid_) {
        pid_ = -1;
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }

  pid_t pid_ = -1;
  int port_ = 0;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::FurnitureRecognizer::Stub> stub_;
};

// The scene exactly as ism-client sends a cloud file.
v1::RecognizeRequest requestFor(const Scene& scene, const Config& c) {
  v1::RecognizeRequest request;
  request.mutable_options()->set_model(fs::path(c.model_path).stem().string());
  *request.mutable_scene() = client::cloudMessage(scene);
  return request;
}

// Servers outlive a benchmark's repetitions (start-up is not what is measured); they are
// stopped when the program ends.
std::map<int, std::unique_ptr<Server>>& servers() {
  static std::map<int, std::unique_ptr<Server>> s;
  return s;
}

Server& serverFor(int threads_per_request) {
  auto& s = servers()[threads_per_request];
  if (!s) s = std::make_unique<Server>(threads_per_request);
  return *s;
}

// One unary Recognize call of the same frame, client to client: encoding, transport, the
// server's decoding and pipeline, the answer. Counters: the server's own stage total.
void BM_GrpcRecognize(benchmark::State& state) {
  setCommon(state);
  const int threads = static_cast<int>(state.range(0));
  std::optional<v1::RecognizeRequest> request;
  Server* server = nullptr;
  try {
    server = &serverFor(threads);
    request = requestFor(inputs().scene, config());
    v1::RecognizeResponse warm;
    const grpc::Status status = server->recognize(*request, &warm);  // first call: channel and caches
    if (!status.ok()) throw std::runtime_error("Recognize failed: " + status.error_message());
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  double server_ms = 0, decode_ms = 0;
  size_t hypotheses = 0;
  for (auto _ : state) {
    v1::RecognizeResponse response;
    const grpc::Status status = server->recognize(*request, &response);
    if (!status.ok()) {
      state.SkipWithError(("Recognize failed: " + status.error_message()).c_str());
      break;
    }
    server_ms += response.result().total_ms();
    for (const auto& t : response.result().timings()) {
      if (t.stage() == "decode") decode_ms += t.ms();
    }
    hypotheses = static_cast<size_t>(response.result().hypotheses_size());
  }
  state.counters["server_total_ms"] = benchmark::Counter(server_ms, benchmark::Counter::kAvgIterations);
  state.counters["server_decode_ms"] = benchmark::Counter(decode_ms, benchmark::Counter::kAvgIterations);
  state.counters["request_MB"] = static_cast<double>(request->ByteSizeLong()) / (1024.0 * 1024.0);
  state.counters["hypotheses"] = static_cast<double>(hypotheses);
}

// The server's resident memory with the model loaded, and after `recognitions` calls. A fresh
// server with its default settings, so that earlier calls are not in its high-water mark.
void BM_ServerMemory(benchmark::State& state) {
  const int recognitions = static_cast<int>(state.range(0));
  for (auto _ : state) {
    try {
      Server server(0);
      const double rss_loaded = server.statusMb("VmRSS"), hwm_loaded = server.statusMb("VmHWM");
      const v1::RecognizeRequest request = requestFor(inputs().scene, config());
      for (int i = 0; i < recognitions; ++i) {
        v1::RecognizeResponse response;
        const grpc::Status status = server.recognize(request, &response);
        if (!status.ok()) throw std::runtime_error("Recognize failed: " + status.error_message());
      }
      state.counters["rss_loaded_MB"] = rss_loaded;
      state.counters["hwm_loaded_MB"] = hwm_loaded;
      state.counters["rss_after_MB"] = server.statusMb("VmRSS");
      state.counters["hwm_after_MB"] = server.statusMb("VmHWM");
    } catch (const std::exception& e) {
      state.SkipWithError(e.what());
      break;
    }
  }
  state.counters["recognitions"] = recognitions;
}

void registerBenchmarks() {
  std::vector<int64_t> threads{1};
  if (processors() > 1) threads.push_back(processors());
  const auto stage = [&](const char* name, void (*fn)(benchmark::State&)) {
    auto* b = benchmark::RegisterBenchmark(name, fn)->ArgName("threads")->Unit(benchmark::kMillisecond)->UseRealTime();
    for (int64_t t : threads) b->Arg(t);
  };
  stage("frame/downsample", BM_Downsample);
  if (inputs().model.front_end.smoothing.enabled) stage("frame/smooth", BM_Smooth);
  // In the order extractFeatures runs them.
  if (inputs().model.front_end.gravity.enabled) stage("frame/gravity", BM_Gravity);
  if (inputs().organized) {
    stage("frame/keypoints", BM_Keypoints);
    stage("frame/normals", BM_Normals);
  } else {
    stage("frame/normals", BM_Normals);
    stage("frame/keypoints", BM_Keypoints);
  }
  stage("frame/describe", BM_Describe);
  stage("frame/activate", BM_Activate);
  stage("frame/vote", BM_Vote);
  stage("frame/hypotheses", BM_Hypotheses);
  stage("frame/verify10", BM_Verify10);
  stage("frame/recognize", BM_Recognize);
  stage("grpc/recognize", BM_GrpcRecognize);
  benchmark::RegisterBenchmark("model/load", BM_ModelLoad)->Unit(benchmark::kMillisecond)->UseRealTime();
  benchmark::RegisterBenchmark("server/memory", BM_ServerMemory)
      ->ArgName("recognitions")
      ->Arg(config().recognitions)
      ->Iterations(1)
      ->Repetitions(1)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
}

int usage(const char* argv0) {
  std::cerr << "usage: " << argv0
            << " [--model FILE.ismm] [--scene FILE.pcd] [--server BINARY] [--recognitions N] [--benchmark_...]\n"
               "  defaults: models/default/furniture.ismm; ../shared/data/real/kinect/tum_desk.pcd, else\n"
               "  models/sample/living_room.pcd; the ism-server of this build; 20 recognitions before the\n"
               "  server's memory is read again. Google Benchmark's flags (--benchmark_filter, \n"
               "  --benchmark_repetitions, --benchmark_out ...) are passed through.\n";
  return 2;
}

}  // namespace ism::bench

int main(int argc, char** argv) {
  using namespace ism::bench;
  benchmark::Initialize(&argc, argv);  // takes out its own --benchmark_* flags
  Config& c = config();
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--help" || arg == "-h") return usage(argv[0]);
    if (!has_value) {
      std::cerr << "ism-bench: " << arg << " is not an option or lacks its value\n";
      return usage(argv[0]);
    }
    const std::string value = argv[++i];
    if (arg == "--model") {
      c.model_path = value;
    } else if (arg == "--scene") {
      c.scene_path = value;
    } else if (arg == "--server") {
      c.server_binary = value;
    } else if (arg == "--recognitions") {
      try {
        c.recognitions = std::stoi(value);
      } catch (const std::exception&) {
        c.recognitions = -1;
      }
      if (c.recognitions < 1) {
        std::cerr << "ism-bench: --recognitions '" << value << "' must be a positive integer\n";
        return 2;
      }
    } else {
      std::cerr << "ism-bench: unknown option " << arg << '\n';
      return usage(argv[0]);
    }
  }
  std::string scene_note = "given";
  if (c.scene_path.empty()) {
    const fs::path kinect = fs::path(ISM_SHARED_DATA_DIR) / "real" / "kinect" / "tum_desk.pcd";
    if (fs::exists(kinect)) {
      c.scene_path = kinect.lexically_normal().string();
      scene_note = "the 640x480 Kinect frame";
    } else {
      c.scene_path = std::string(ISM_SOURCE_DIR) + "/models/sample/living_room.pcd";
      scene_note = "FALLBACK: " + kinect.string() + " is absent, using the sample scene instead";
      std::cerr << "ism-bench: " << scene_note << '\n';
    }
  }
  try {
    prepareInputs();
  } catch (const std::exception& e) {
    std::cerr << "ism-bench: " << e.what() << '\n';
    return 1;
  }
  const Inputs& in = inputs();
  benchmark::AddCustomContext("scene", c.scene_path);
  benchmark::AddCustomContext("scene_note", scene_note);
  benchmark::AddCustomContext("scene_points", std::to_string(in.scene.cloud->size()));
  benchmark::AddCustomContext("scene_keypoints", std::to_string(in.features.size()));
  benchmark::AddCustomContext("model", c.model_path);
  benchmark::AddCustomContext("categories", std::to_string(in.model.categories.size()));
  benchmark::AddCustomContext("processors", std::to_string(processors()));
  registerBenchmarks();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  servers().clear();
  return 0;
}
