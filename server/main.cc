// ism-server: the furniture recognition gRPC service. Parse the options, run, and on SIGTERM or
// SIGINT drain: stop taking calls, let the running ones finish (up to --drain-seconds), exit 0.
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <malloc.h>

#include <algorithm>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <memory>

#include "server/health_probe.h"
#include "server/options.h"
#include "server/server.h"

namespace {

// Blocked before any thread exists, so that every thread inherits the mask and only sigwait()
// ever sees the stop signals.
sigset_t blockStopSignals() {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  return signals;
}

void setUpLogging(const std::string& level) {
  spdlog::set_default_logger(spdlog::stderr_color_mt("ism-server"));
  spdlog::set_level(spdlog::level::from_str(level));
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v");
}

}  // namespace

int main(int argc, char** argv) {
  // A recognition allocates and frees tens of MB on its worker thread; glibc would hand that
  // memory back to the kernel after every request and fault it in again for the next one. Blocks
  // below 32 MB (the largest glibc allows here) come from the heap, which keeps up to 256 MB free.
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 256 * 1024 * 1024);
  const sigset_t stop_signals = blockStopSignals();

  int exit_code = 0;
  const auto options = ism::server::parseServerOptions(argc, argv, &exit_code);
  if (!options) return exit_code;
  if (options->health_check) {
    return ism::server::runHealthCheck(*options, std::chrono::seconds(3), std::cout, std::cerr);
  }
  setUpLogging(options->log_level);
  // glibc gives each thread that allocates an arena of its own (up to 8 per core), and each arena
  // keeps what its requests freed: a 2-worker server held 225-254 MB after soaks at saturation,
  // 133 MB with two arenas at the same throughput (docs/PERFORMANCE.md, "Soak"). One arena per
  // worker, at least two; MALLOC_ARENA_MAX in the environment still decides when set.
  if (std::getenv("MALLOC_ARENA_MAX") == nullptr) mallopt(M_ARENA_MAX, std::max(2, options->threads));

  // Reflection is the binary's, not the server library's: tests link the library with their own
  // reflection stubs, and two copies of reflection.proto's descriptors abort at start-up.
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  std::unique_ptr<ism::server::Server> server;
  try {
    server = std::make_unique<ism::server::Server>(*options);
  } catch (const std::exception& e) {
    spdlog::critical("{}", e.what());
    return 1;
  }
  int signal_number = 0;
  sigwait(&stop_signals, &signal_number);
  spdlog::info("{}", strsignal(signal_number));
  server->drain();
  // Exit without destroying the server: gRPC's own shutdown would answer calls arriving
  // meanwhile CANCELLED (grpc/grpc#41785), which clients do not retry. Every call we took is
  // answered by now; a call still on its way finds the connection closed: UNAVAILABLE. The
  // loggers are flushed, not dropped: work stopped past the drain time may still be logging on
  // its thread, and a dropped default logger is a null pointer to it.
  spdlog::apply_all([](const std::shared_ptr<spdlog::logger>& logger) { logger->flush(); });
  std::_Exit(0);
}
