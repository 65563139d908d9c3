#pragma once
// Shared by the service tests: a tiny model trained once and cached in the build tree, the real
// ism-server binary started on free ports, small synthetic scenes, and request builders.
#include <grpcpp/grpcpp.h>
#include <sys/types.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "core/scanner/scanner.h"
#include "ism/v1/service.grpc.pb.h"

namespace ism::testing {

// A TCP port on 127.0.0.1 that nothing listens on right now.
int freePort();

// Trains (first call in the build tree) or reuses a two-category model; returns the directory
// holding it as default.ismm. Cached because every test process starts its own server.
std::string tinyModelDirectory();

// A running ism-server. The destructor kills it (SIGKILL) if the test did not stop it.
class ServerProcess {
 public:
  // Extra flags are appended (e.g. "--max-points", "5000"; "--models" replaces the tiny model's).
  // Waits for health SERVING, asked over `credentials` (plain text when null; TLS servers need
  // SslCredentials). `port` 0 picks a free one; a restarted server takes its predecessor's so
  // that clients find it again. With `log_file`, the server's log (its stderr) goes there
  // instead of the test's output, for tests that read it.
  explicit ServerProcess(const std::vector<std::string>& extra_flags = {},
                         std::shared_ptr<grpc::ChannelCredentials> credentials = nullptr, int port = 0,
                         const std::string& log_file = "");
  ~ServerProcess();
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  int metricsPort() const { return metrics_port_; }
  std::shared_ptr<grpc::Channel> channel() const { return channel(credentials_); }
  // A channel with its own subchannels: one test's failed handshake never leaks into another's.
  std::shared_ptr<grpc::Channel> channel(const std::shared_ptr<grpc::ChannelCredentials>& credentials) const;
  // SIGTERM, then the exit code (-1 when it did not exit within `timeout` or died of a signal).
  int terminate(std::chrono::seconds timeout = std::chrono::seconds(30));
  // SIGKILL: a crash, with no draining.
  void kill();
  // The body of GET /metrics.
  std::string metrics() const;

 private:
  // Spawns the server on port_ and waits for SERVING; false when it exited during start-up.
  bool start(const std::vector<std::string>& extra_flags, const std::string& models, const std::string& log_file);

  pid_t pid_ = -1;
  int port_ = 0;
  int metrics_port_ = 0;
  std::shared_ptr<grpc::ChannelCredentials> credentials_;
};

// 160x120 frames of procedural furniture on a floor; `frame` moves the camera a little so a
// stream is not the same image over and over.
SyntheticScene smallScene(int frame = 0, int width = 160, int height = 120);

// Scenes as the wire carries them.
v1::Scene cloudMessage(const Scene& scene);
v1::Scene rawDepthMessage(const DepthImage& image, float depth_scale = 1000.0f);
v1::Scene pngDepthMessage(const DepthImage& image, float depth_scale = 1000.0f);

std::string runCommand(const std::string& command, int* exit_code);  // stdout+stderr

}  // namespace ism::testing
