#include "server/server.h"

#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <thread>

#include "core/common/error.h"

namespace ism::server {
namespace {

// How long work given up at the end of the drain may take to notice.
constexpr auto kAbandonGrace = std::chrono::seconds(2);

AccessParams accessParams(const ServerOptions& options) {
  AccessParams params;
  if (!options.token_file.empty()) params.tokens = readTokenFile(options.token_file);
  if (!options.admin_token_file.empty()) params.admin_tokens = readTokenFile(options.admin_token_file);
  params.max_streams_per_client = options.max_streams_per_client;
  return params;
}

}  // namespace

Server::Server(const ServerOptions& options)
    : options_(options),
      models_(options.model_dir, options.max_model_mb << 20),
      metrics_(options.metrics_listen),
      admission_(options.max_queued_mb << 20, &health_),
      pool_(options.threads, options.threads_per_request),
      access_(accessParams(options)) {
  models_.loadDirectory();
  for (const auto& model : models_.list()) {
    spdlog::info("model {}@{}: {} categories from {} ({:.0f}ms)", model->name, model->info.version(),
                 model->info.categories_size(), model->info.path(), model->info.load_ms());
  }
  if (models_.size() == 0) spdlog::warn("no *.ismm in {}: load models with LoadModel", options.model_dir);
  metrics_.setLoadedModels(models_.size());
  health_.setModels(models_.size());
  warnAboutExposure();
  service_ = std::make_unique<RecognizerService>(
      ServiceContext{models_, pool_, admin_pool_, metrics_, health_, admission_, options.limits}, access_);

  const auto credentials = options.tls_cert.empty()
                               ? grpc::InsecureServerCredentials()
                               : tlsServerCredentials(options.tls_cert, options.tls_key, options.tls_client_ca);
  grpc::EnableDefaultHealthCheckService(true);
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(options.listen, credentials, &port);
  builder.SetMaxReceiveMessageSize(options.max_message_mb * 1024 * 1024);
  builder.SetMaxSendMessageSize(options.max_message_mb * 1024 * 1024);
  builder.RegisterService(service_.get());
  server_ = builder.BuildAndStart();
  if (!server_ || port == 0) throw Error(ErrorCode::kIo, "cannot listen on " + options.listen + " (--listen)");
  health_.attach(server_->GetHealthCheckService());
  spdlog::info("listening on {} (port {}, {}{}, tokens {}), {} worker threads x {} per request, metrics {}",
               options.listen, port, options.tls_cert.empty() ? "plain text" : "TLS",
               options.tls_client_ca.empty() ? "" : " with client certificates",
               access_.authEnabled() ? "required" : "off", options.threads, options.threads_per_request,
               options.metrics_listen.empty() ? "off" : options.metrics_listen);
}

void Server::warnAboutExposure() const {
  if (!isLoopbackAddress(options_.listen)) {
    if (options_.tls_cert.empty()) {
      spdlog::warn("{} is reachable from other machines without TLS: scenes{} cross the network readable by anyone",
                   options_.listen, access_.authEnabled() ? " and tokens" : "");
    }
    if (!access_.authEnabled()) {
      spdlog::warn("{} is reachable from other machines without --token-file: anyone may call every RPC",
                   options_.listen);
    }
  }
  // /metrics is plain HTTP without tokens whatever the gRPC side uses.
  if (!options_.metrics_listen.empty() && !isLoopbackAddress(options_.metrics_listen)) {
    spdlog::warn("/metrics on {} is reachable from other machines, in plain HTTP without tokens{}: give "
                 "--metrics-listen 127.0.0.1:9464, or keep the port behind a firewall",
                 options_.metrics_listen,
                 options_.tls_cert.empty() && !access_.authEnabled() ? "" : " (unlike the gRPC port)");
  }
  if (access_.authEnabled() && options_.admin_token_file.empty()) {
    spdlog::info("no --admin-token-file: LoadModel, UnloadModel and ReloadModels are refused");
  }
}

void Server::drain() {
  spdlog::info("draining running calls (up to {}s)", options_.drain_seconds);
  const auto start = std::chrono::steady_clock::now();
  // Health first, so load balancers stop sending new calls while the old ones finish.
  health_.setDraining();
  service_->beginShutdown();
  const auto drain_end = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                     std::chrono::duration<double>(options_.drain_seconds));
  const auto waitUntil = [&](std::chrono::steady_clock::time_point end, std::chrono::milliseconds quiet) {
    while (!service_->idle(quiet) && std::chrono::steady_clock::now() < end) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return service_->idle(quiet);
  };
  if (!waitUntil(drain_end, std::chrono::milliseconds(100)) && service_->openCalls() > 0) {
    spdlog::warn("{} calls still open after the {}s drain: stopping their work", service_->openCalls(),
                 options_.drain_seconds);
    service_->abandonRunning();
    // Work polls for the stop between its steps; a step that does not end within this is cut
    // by the exit, and its caller sees the connection close (UNAVAILABLE too).
    waitUntil(std::chrono::steady_clock::now() + kAbandonGrace, std::chrono::milliseconds(0));
  }
  spdlog::info("stopped after {:.0f}ms of draining, {} calls still open",
               std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count(),
               service_->openCalls());
}

}  // namespace ism::server
