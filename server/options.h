#pragma once
// Everything ism-server is told on its command line (or by the ISM_* variable of each flag, for
// containers), parsed in one place into one struct.
#include <cstddef>
#include <optional>
#include <string>

#include "server/conversion.h"

namespace ism::server {

struct ServerOptions {
  std::string listen = "0.0.0.0:50051";
  std::string model_dir;       // every *.ismm in it is loaded, named by its stem
  int threads = 1;             // recognitions at once (default: the cores)
  int threads_per_request = 0; // OpenMP threads of one recognition; 0: cores / threads, at least 1
  int max_message_mb = 64;     // largest request or response
  size_t max_model_mb = 256;   // largest model file read
  size_t max_queued_mb = 256;  // requests held at once, queued or running, as sent (0: no bound)
  InputLimits limits;
  // Empty: no /metrics. ":PORT" takes the host of `listen`, so that a server kept to loopback
  // does not expose its metrics to the network (resolved by parseServerOptions).
  std::string metrics_listen = ":9464";
  double drain_seconds = 10;   // on SIGTERM, how long running calls may take to finish
  std::string log_level = "info";
  // TLS (cert and key together; client_ca: mTLS) and bearer tokens, all from files.
  std::string tls_cert, tls_key, tls_client_ca;
  std::string token_file, admin_token_file;
  size_t max_streams_per_client = 0;  // 0: no limit
  // Ask the server these options describe for its health and exit (the image's HEALTHCHECK).
  bool health_check = false;
};

// `metrics_listen` with a leading ':' completed by the host of `grpc_listen` (127.0.0.1 for a
// unix socket or "localhost", which the HTTP server cannot bind by name); otherwise unchanged.
std::string metricsAddress(const std::string& grpc_listen, const std::string& metrics_listen);

// The options of `argv` and the environment. nullopt when the process should exit instead
// (--help, or a command line that does not parse: the message is printed), with `*exit_code`.
std::optional<ServerOptions> parseServerOptions(int argc, char** argv, int* exit_code);

}  // namespace ism::server
