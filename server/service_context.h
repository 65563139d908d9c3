#pragma once
// What every RPC of the service shares: the models, the worker pool, the metrics, the input
// limits, and the one path from a wire scene to a wire result.
#include <grpcpp/support/server_callback.h>
#include <grpcpp/server_context.h>

#include <atomic>
#include <string>

#include "core/common/types.h"
#include "server/admission.h"
#include "server/conversion.h"
#include "server/health.h"
#include "server/metrics.h"
#include "server/model_registry.h"
#include "server/worker_pool.h"

namespace ism::server {

struct ServiceContext {
  ModelRegistry& models;
  WorkerPool& pool;        // recognitions
  WorkerPool& admin_pool;  // LoadModel, UnloadModel, ReloadModels
  Metrics& metrics;
  Health& health;
  Admission& admission;  // recognitions: unary requests and stream frames
  InputLimits limits;
  // Set once the drain time is over: the work still running is given up (may be null).
  const std::atomic<bool>* abandoned = nullptr;

  // Decode, recognise, encode. Throws ism::Error; logs one line tagged with `request_id`.
  void recognize(const std::string& request_id, const v1::Scene& scene, const v1::RecognitionOptions& options,
                 const ShouldStop& should_stop, v1::RecognitionResult* out) const;

  // True once the client cancelled, the deadline passed, the server gave the work up or `also`
  // (may be null) is set: the pipeline stops working for a caller that is gone.
  ShouldStop stopper(grpc::CallbackServerContext* context, const std::atomic<bool>* also = nullptr) const;
  bool workAbandoned() const { return abandoned != nullptr && abandoned->load(); }

  // The pipeline reports any stop as CANCELLED; say why: DEADLINE_EXCEEDED when the deadline
  // passed, UNAVAILABLE (send it again) when the server gave the call up as it shut down.
  grpc::Status whyStopped(grpc::CallbackServerContext* context, grpc::Status status) const;
};

// UNAVAILABLE, so that clients send the call again (to another server, or after the restart):
// for a call that arrives while the server shuts down, and for one still running when the
// shutdown's drain time is over.
grpc::Status refusedWhileShuttingDown();
grpc::Status givenUpAtShutdown();

// `given` when not empty, else a new process-unique id.
std::string requestId(const std::string& given);

}  // namespace ism::server
