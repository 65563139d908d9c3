// ism-server: the furniture recognition gRPC service. Every flag has an ISM_* environment
// variable fallback (for containers). SIGTERM/SIGINT stop accepting calls, let the running ones
// finish (up to --drain-seconds), and exit 0. Secrets come from files, never from flags, so
// that they do not show in `ps`.
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <malloc.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <thread>

#include "server/auth.h"
#include "server/recognizer_service.h"

namespace fs = std::filesystem;

namespace {

// models/default next to an installed binary (PREFIX/share/ism/...), else in the source tree.
std::string defaultModelDirectory() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  const fs::path installed = exe.parent_path().parent_path() / "share" / "ism" / "models" / "default";
  if (!ec && fs::is_directory(installed)) return installed.string();
  return ISM_SOURCE_MODEL_DIR;
}

}  // namespace

int main(int argc, char** argv) {
  // Keep freed memory for the next request. A recognition allocates and frees tens of MB (sort
  // buffers, grids, Hough blocks) on its worker thread; with glibc's defaults the freed pages
  // went back to the kernel after every request and the next one faulted them in again: on
  // two threads a Kinect frame took 52 ms in the server against 46 ms in process (downsample
  // alone 8.2 against 5.0 ms). Blocks below 32 MB (the largest glibc allows here) come from
  // the heap, and a heap keeps up to 256 MB free at its top.
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 256 * 1024 * 1024);

  // Block the stop signals before any thread exists, so that every thread inherits the mask
  // and only sigwait() below ever sees them.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  CLI::App app{"ism-server: furniture recognition with 3D Implicit Shape Models over gRPC"};
  std::string listen = "0.0.0.0:50051";
  std::string model_dir = defaultModelDirectory();
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  int threads = cores;
  int threads_per_request = 0;  // 0: cores / worker threads
  int max_message_mb = 64;
  std::string metrics_listen = "0.0.0.0:9464";
  std::string log_level = "info";
  ism::server::InputLimits limits;
  double drain_seconds = 10;
  std::string tls_cert, tls_key, tls_client_ca, token_file, admin_token_file;
  size_t max_streams_per_client = 0;
  app.add_option("--listen", listen, "gRPC address")->envname("ISM_LISTEN")->capture_default_str();
  app.add_option("--models", model_dir, "directory whose *.ismm files are loaded (name = file stem)")
      ->envname("ISM_MODELS")
      ->capture_default_str();
  app.add_option("--threads", threads, "recognition worker threads")
      ->envname("ISM_THREADS")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  app.add_option("--threads-per-request", threads_per_request,
                 "OpenMP threads one recognition uses (0: cores / --threads, at least 1); more lowers one "
                 "frame's latency, fewer raises throughput under load")
      ->envname("ISM_THREADS_PER_REQUEST")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  app.add_option("--max-message-mb", max_message_mb, "largest request or response (a raw 640x480 XYZRGB frame is 4.6 MB)")
      ->envname("ISM_MAX_MESSAGE_MB")
      ->check(CLI::Range(1, 2047))
      ->capture_default_str();
  app.add_option("--max-points", limits.max_points, "largest cloud accepted (points)")
      ->envname("ISM_MAX_POINTS")
      ->capture_default_str();
  app.add_option("--max-pixels", limits.max_pixels, "largest depth image accepted (pixels)")
      ->envname("ISM_MAX_PIXELS")
      ->capture_default_str();
  app.add_option("--metrics-listen", metrics_listen, "Prometheus /metrics address; empty disables it")
      ->envname("ISM_METRICS_LISTEN")
      ->capture_default_str();
  app.add_option("--drain-seconds", drain_seconds, "on SIGTERM, how long running calls may take to finish")
      ->envname("ISM_DRAIN_SECONDS")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical, off")
      ->envname("ISM_LOG_LEVEL")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}))
      ->capture_default_str();
  auto* cert_option = app.add_option("--tls-cert", tls_cert, "PEM certificate chain: serve TLS instead of plain text")
                          ->envname("ISM_TLS_CERT")
                          ->check(CLI::ExistingFile);
  auto* key_option = app.add_option("--tls-key", tls_key, "PEM private key of --tls-cert")
                         ->envname("ISM_TLS_KEY")
                         ->check(CLI::ExistingFile);
  cert_option->needs(key_option);
  key_option->needs(cert_option);
  app.add_option("--tls-client-ca", tls_client_ca,
                 "PEM CA certificates: require client certificates signed by them (mTLS)")
      ->envname("ISM_TLS_CLIENT_CA")
      ->check(CLI::ExistingFile)
      ->needs(cert_option);
  app.add_option("--token-file", token_file,
                 "bearer tokens, one per line: every RPC but health and reflection then needs one")
      ->envname("ISM_TOKEN_FILE")
      ->check(CLI::ExistingFile);
  app.add_option("--admin-token-file", admin_token_file,
                 "bearer tokens that may also call LoadModel, UnloadModel and ReloadModels")
      ->envname("ISM_ADMIN_TOKEN_FILE")
      ->check(CLI::ExistingFile);
  app.add_option("--max-streams-per-client", max_streams_per_client,
                 "concurrent StreamFrames calls per client (its token, else its host); 0: no limit")
      ->envname("ISM_MAX_STREAMS_PER_CLIENT")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  spdlog::set_default_logger(spdlog::stderr_color_mt("ism-server"));
  spdlog::set_level(spdlog::level::from_str(log_level));
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v");

  try {
    ism::server::ModelRegistry models(model_dir);
    models.loadDirectory();
    for (const auto& model : models.list()) {
      spdlog::info("model {}@{}: {} categories from {} ({:.0f}ms)", model->name, model->info.version(),
                   model->info.categories_size(), model->info.path(), model->info.load_ms());
    }
    if (models.size() == 0) spdlog::warn("no *.ismm in {}: load models with LoadModel", model_dir);

    ism::server::Metrics metrics(metrics_listen);
    metrics.setLoadedModels(models.size());
    // Declared before the server so that it outlives every call the server finishes.
    if (threads_per_request == 0) threads_per_request = std::max(1, cores / threads);
    ism::server::WorkerPool pool(threads, threads_per_request);
    ism::server::AccessParams access_params;
    if (!token_file.empty()) access_params.tokens = ism::server::readTokenFile(token_file);
    if (!admin_token_file.empty()) access_params.admin_tokens = ism::server::readTokenFile(admin_token_file);
    access_params.max_streams_per_client = max_streams_per_client;
    ism::server::AccessControl access(access_params);
    const auto credentials = tls_cert.empty() ? grpc::InsecureServerCredentials()
                                              : ism::server::tlsServerCredentials(tls_cert, tls_key, tls_client_ca);
    if (!ism::server::isLoopbackAddress(listen)) {
      if (tls_cert.empty()) {
        spdlog::warn("{} is reachable from other machines without TLS: scenes{} cross the network readable by anyone",
                     listen, access.authEnabled() ? " and tokens" : "");
      }
      if (!access.authEnabled()) {
        spdlog::warn("{} is reachable from other machines without --token-file: anyone may call every RPC", listen);
      }
    }
    if (access.authEnabled() && access_params.admin_tokens.empty()) {
      spdlog::info("no --admin-token-file: LoadModel, UnloadModel and ReloadModels are refused");
    }
    ism::server::RecognizerService service({models, pool, metrics, limits}, access);

    grpc::EnableDefaultHealthCheckService(true);
    grpc::reflection::InitProtoReflectionServerBuilderPlugin();
    grpc::ServerBuilder builder;
    int port = 0;
    builder.AddListeningPort(listen, credentials, &port);
    builder.SetMaxReceiveMessageSize(max_message_mb * 1024 * 1024);
    builder.SetMaxSendMessageSize(max_message_mb * 1024 * 1024);
    builder.RegisterService(&service);
    std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
    if (!server || port == 0) {
      spdlog::critical("cannot listen on {}", listen);
      return 1;
    }
    spdlog::info("listening on {} (port {}, {}{}, tokens {}), {} worker threads x {} per request, metrics {}", listen, port,
                 tls_cert.empty() ? "plain text" : "TLS", tls_client_ca.empty() ? "" : " with client certificates",
                 access.authEnabled() ? "required" : "off", threads, threads_per_request,
                 metrics_listen.empty() ? "off" : metrics_listen);

    int signal_number = 0;
    sigwait(&stop_signals, &signal_number);
    spdlog::info("{}: draining running calls (up to {}s)", strsignal(signal_number), drain_seconds);
    // Health first, so load balancers stop sending new calls while the old ones finish.
    server->GetHealthCheckService()->SetServingStatus(false);
    const auto drain_start = std::chrono::steady_clock::now();
    const auto drain_end =
        std::chrono::system_clock::now() +
        std::chrono::duration_cast<std::chrono::system_clock::duration>(std::chrono::duration<double>(drain_seconds));
    // Our drain first (new calls refused UNAVAILABLE, streams ended), gRPC's once nothing runs.
    service.beginShutdown();
    while (!service.idle(std::chrono::milliseconds(100)) && std::chrono::system_clock::now() < drain_end) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    server->Shutdown(drain_end);
    spdlog::info("stopped after {:.0f}ms of draining",
                 std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - drain_start).count());
  } catch (const std::exception& e) {
    spdlog::critical("{}", e.what());
    return 1;
  }
  return 0;
}
