#include "server/options.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <filesystem>
#include <thread>

#include "core/common/cli_checks.h"

namespace ism::server {
namespace {

namespace fs = std::filesystem;

// models/default next to an installed binary (PREFIX/share/ism/...), else in the source tree.
std::string defaultModelDirectory() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  const fs::path installed = exe.parent_path().parent_path() / "share" / "ism" / "models" / "default";
  if (!ec && fs::is_directory(installed)) return installed.string();
  return ISM_SOURCE_MODEL_DIR;
}

int cores() { return static_cast<int>(std::max(1u, std::thread::hardware_concurrency())); }

}  // namespace

std::string metricsAddress(const std::string& grpc_listen, const std::string& metrics_listen) {
  if (metrics_listen.empty() || metrics_listen[0] != ':') return metrics_listen;
  const size_t colon = grpc_listen.rfind(':');
  std::string host = colon == std::string::npos ? "" : grpc_listen.substr(0, colon);
  if (grpc_listen.rfind("unix:", 0) == 0 || host == "localhost" || host.empty()) host = "127.0.0.1";
  return host + metrics_listen;
}

std::optional<ServerOptions> parseServerOptions(int argc, char** argv, int* exit_code) {
  ServerOptions o;
  o.model_dir = defaultModelDirectory();
  o.threads = cores();

  CLI::App app{"ism-server: furniture recognition with 3D Implicit Shape Models over gRPC"};
  app.add_option("--listen", o.listen, "gRPC address")->envname("ISM_LISTEN")->capture_default_str();
  app.add_option("--models", o.model_dir, "directory whose *.ismm files are loaded (name = file stem)")
      ->envname("ISM_MODELS")
      ->capture_default_str();
  app.add_option("--threads", o.threads, "recognition worker threads")
      ->envname("ISM_THREADS")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  app.add_option("--threads-per-request", o.threads_per_request,
                 "OpenMP threads one recognition uses (0: cores / --threads, at least 1); more lowers one "
                 "frame's latency, fewer raises throughput under load")
      ->envname("ISM_THREADS_PER_REQUEST")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  app.add_option("--max-message-mb", o.max_message_mb,
                 "largest request or response (a raw 640x480 XYZRGB frame is 4.6 MB)")
      ->envname("ISM_MAX_MESSAGE_MB")
      ->check(CLI::Range(1, 2047))
      ->capture_default_str();
  app.add_option("--max-model-mb", o.max_model_mb, "largest model file loaded (the shipped one is 13 MB)")
      ->envname("ISM_MAX_MODEL_MB")
      ->check(CLI::Range(1, 1 << 20))
      ->capture_default_str();
  app.add_option("--max-queued-mb", o.max_queued_mb,
                 "MB of recognition requests (as sent) held at once, queued or running; beyond it requests are "
                 "refused RESOURCE_EXHAUSTED at once (0: no bound)")
      ->envname("ISM_MAX_QUEUED_MB")
      ->check(CLI::Range(size_t{0}, size_t{1} << 20))
      ->capture_default_str();
  app.add_option("--max-points", o.limits.max_points, "largest cloud accepted (points)")
      ->envname("ISM_MAX_POINTS")
      ->capture_default_str();
  app.add_option("--max-pixels", o.limits.max_pixels, "largest depth image accepted (pixels)")
      ->envname("ISM_MAX_PIXELS")
      ->capture_default_str();
  app.add_option("--max-range-m", o.limits.max_range_m,
                 "points farther than this from the scene's sensor origin are dropped (counted in the result)")
      ->envname("ISM_MAX_RANGE_M")
      ->check(CLI::Range(0.1f, 1e6f))
      ->capture_default_str();
  app.add_option("--metrics-listen", o.metrics_listen,
                 "Prometheus /metrics address (plain HTTP); ':PORT' listens on --listen's host; empty disables it")
      ->envname("ISM_METRICS_LISTEN")
      ->capture_default_str();
  app.add_option("--drain-seconds", o.drain_seconds, "on SIGTERM, how long running calls may take to finish")
      ->envname("ISM_DRAIN_SECONDS")
      ->check(ism::cli::nonNegative())
      ->capture_default_str();
  app.add_option("--log-level", o.log_level, "trace, debug, info, warn, error, critical, off")
      ->envname("ISM_LOG_LEVEL")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}))
      ->capture_default_str();
  auto* cert = app.add_option("--tls-cert", o.tls_cert, "PEM certificate chain: serve TLS instead of plain text")
                   ->envname("ISM_TLS_CERT")
                   ->check(CLI::ExistingFile);
  auto* key = app.add_option("--tls-key", o.tls_key, "PEM private key of --tls-cert")
                  ->envname("ISM_TLS_KEY")
                  ->check(CLI::ExistingFile);
  cert->needs(key);
  key->needs(cert);
  app.add_option("--tls-client-ca", o.tls_client_ca,
                 "PEM CA certificates: require client certificates signed by them (mTLS)")
      ->envname("ISM_TLS_CLIENT_CA")
      ->check(CLI::ExistingFile)
      ->needs(cert);
  app.add_option("--token-file", o.token_file,
                 "bearer tokens, one per line: every RPC but health and reflection then needs one")
      ->envname("ISM_TOKEN_FILE")
      ->check(CLI::ExistingFile);
  app.add_option("--admin-token-file", o.admin_token_file,
                 "bearer tokens that may also call LoadModel, UnloadModel and ReloadModels")
      ->envname("ISM_ADMIN_TOKEN_FILE")
      ->check(CLI::ExistingFile);
  app.add_option("--max-streams-per-client", o.max_streams_per_client,
                 "concurrent StreamFrames calls per client (its token, else its host); 0: no limit")
      ->envname("ISM_MAX_STREAMS_PER_CLIENT")
      ->capture_default_str();
  // No environment variable: one set for a container would turn its server into a probe.
  app.add_flag("--health-check", o.health_check,
               "ask the server at --listen (with the --tls-* files) for its health and exit: 0 when SERVING");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    *exit_code = app.exit(e);
    return std::nullopt;
  }
  o.metrics_listen = metricsAddress(o.listen, o.metrics_listen);
  if (o.threads_per_request == 0) o.threads_per_request = std::max(1, cores() / o.threads);
  return o;
}

}  // namespace ism::server
