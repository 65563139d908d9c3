#pragma once
// ism-server as one object: built from its options it loads the models, listens and serves
// until drain() stops it.
#include <grpcpp/server.h>

#include <memory>

#include "server/admission.h"
#include "server/auth.h"
#include "server/health.h"
#include "server/metrics.h"
#include "server/model_registry.h"
#include "server/options.h"
#include "server/recognizer_service.h"
#include "server/worker_pool.h"

namespace ism::server {

class Server {
 public:
  // Loads the models and starts serving. Throws ism::Error when a model, a certificate or a
  // token file is bad, or an address cannot be bound.
  explicit Server(const ServerOptions& options);

  // After a stop signal: health says NOT_SERVING, new calls are refused UNAVAILABLE, running
  // ones get up to drain_seconds to finish; what still runs then is stopped and answered
  // UNAVAILABLE. Returns when no call is open (or the little time given for that is over): the
  // process should then exit without destroying the Server (see main.cc).
  void drain();

 private:
  void warnAboutExposure() const;

  const ServerOptions options_;
  // Declared in the order they are needed: the gRPC server last, so that it is destroyed
  // first and every call it finishes finds the rest still there.
  ModelRegistry models_;
  Metrics metrics_;
  Health health_;
  Admission admission_;
  WorkerPool pool_;
  WorkerPool admin_pool_{1, 1};
  AccessControl access_;
  std::unique_ptr<RecognizerService> service_;
  std::unique_ptr<grpc::Server> server_;
};

}  // namespace ism::server
