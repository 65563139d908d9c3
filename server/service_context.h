#pragma once
// What every RPC of the service shares: the models, the worker pool, the metrics, the input
// limits, and the one path from a wire scene to a wire result.
#include <grpcpp/support/server_callback.h>
#include <grpcpp/server_context.h>

#include <atomic>
#include <string>

#include "core/common/types.h"
#include "server/conversion.h"
#include "server/metrics.h"
#include "server/model_registry.h"
#include "server/worker_pool.h"

namespace ism::server {

struct ServiceContext {
  ModelRegistry& models;
  WorkerPool& pool;
  Metrics& metrics;
  InputLimits limits;

  // Decode, recognise, encode. Throws ism::Error; logs one line tagged with `request_id`.
  void recognize(const std::string& request_id, const v1::Scene& scene, const v1::RecognitionOptions& options,
                 const ShouldStop& should_stop, v1::RecognitionResult* out) const;
};

// True once the client cancelled, the deadline passed or `stopped` (may be null) is set, so
// the pipeline stops working for a caller that is gone.
ShouldStop callStopper(grpc::CallbackServerContext* context, const std::atomic<bool>* stopped = nullptr);

// The pipeline reports any stop as CANCELLED; say DEADLINE_EXCEEDED when that is the reason.
grpc::Status withDeadlineReason(grpc::CallbackServerContext* context, grpc::Status status);

// `given` when not empty, else a new process-unique id.
std::string requestId(const std::string& given);

}  // namespace ism::server
