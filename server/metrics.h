#pragma once
// Prometheus metrics: requests by RPC and status code, latency per RPC and per pipeline
// stage, active streams, frames dropped by LATEST_FRAME_WINS, loaded models, and the process's
// memory, CPU time and open files. Served over HTTP at /metrics when a listen address is given.
// deploy/grafana/ism-dashboard.json charts them.
#include <grpcpp/support/status.h>
#include <prometheus/counter.h>
#include <prometheus/exposer.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

#include <memory>
#include <string>

#include "core/common/types.h"
#include "server/process_metrics.h"

namespace ism::server {

class Metrics {
 public:
  // Empty `listen` keeps counting but serves nothing. Throws ism::Error naming the address when
  // it cannot be bound.
  explicit Metrics(const std::string& listen);

  void recordRequest(const std::string& rpc, grpc::StatusCode code, double seconds);
  void recordStages(const StageTimings& timings);
  void callOpened() { open_calls_.Increment(); }
  void callClosed() { open_calls_.Decrement(); }
  void streamOpened() { active_streams_.Increment(); }
  void streamClosed() { active_streams_.Decrement(); }
  void framesSkipped(size_t count) { skipped_frames_.Increment(static_cast<double>(count)); }
  void setLoadedModels(size_t count) { loaded_models_.Set(static_cast<double>(count)); }

 private:
  std::shared_ptr<prometheus::Registry> registry_ = std::make_shared<prometheus::Registry>();
  std::shared_ptr<ProcessMetrics> process_ = std::make_shared<ProcessMetrics>();
  std::unique_ptr<prometheus::Exposer> exposer_;
  prometheus::Family<prometheus::Counter>& requests_;
  prometheus::Family<prometheus::Histogram>& request_seconds_;
  prometheus::Family<prometheus::Histogram>& stage_seconds_;
  prometheus::Gauge& open_calls_;
  prometheus::Gauge& active_streams_;
  prometheus::Counter& skipped_frames_;
  prometheus::Gauge& loaded_models_;
};

}  // namespace ism::server
