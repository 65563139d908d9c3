#include "server/metrics.h"

#include "core/common/error.h"
#include "server/status_mapping.h"

namespace ism::server {
namespace {

// 1 ms .. ~33 s in factors of 2: covers a model listing as well as a full 640x480 frame.
const prometheus::Histogram::BucketBoundaries& latencyBuckets() {
  static const auto buckets = [] {
    prometheus::Histogram::BucketBoundaries b;
    for (double edge = 0.001; edge < 40; edge *= 2) b.push_back(edge);
    return b;
  }();
  return buckets;
}

}  // namespace

Metrics::Metrics(const std::string& listen)
    : requests_(prometheus::BuildCounter()
                    .Name("ism_requests_total")
                    .Help("RPCs (stream frames count one each under StreamFrames.frame) by status code")
                    .Register(*registry_)),
      request_seconds_(prometheus::BuildHistogram()
                           .Name("ism_request_duration_seconds")
                           .Help("RPC latency by method")
                           .Register(*registry_)),
      stage_seconds_(prometheus::BuildHistogram()
                         .Name("ism_stage_duration_seconds")
                         .Help("Recognition pipeline stage durations")
                         .Register(*registry_)),
      open_calls_(prometheus::BuildGauge()
                      .Name("ism_open_calls")
                      .Help("Unary calls received and not answered yet (streams: ism_active_streams)")
                      .Register(*registry_)
                      .Add({})),
      active_streams_(prometheus::BuildGauge()
                          .Name("ism_active_streams")
                          .Help("StreamFrames calls in progress")
                          .Register(*registry_)
                          .Add({})),
      skipped_frames_(prometheus::BuildCounter()
                          .Name("ism_skipped_frames_total")
                          .Help("Stream frames dropped by LATEST_FRAME_WINS")
                          .Register(*registry_)
                          .Add({})),
      loaded_models_(prometheus::BuildGauge()
                         .Name("ism_loaded_models")
                         .Help("Models currently loaded")
                         .Register(*registry_)
                         .Add({})) {
  if (listen.empty()) return;
  // A scrape is one short request: a connection that sends nothing is closed after
  // request_timeout_ms, so that a few idle or half-open connections cannot hold every thread
  // (civetweb's default waits 30 s with 2 threads) and make scrapes time out.
  std::vector<std::string> options{"listening_ports", listen,        "num_threads",       "8",
                                   "request_timeout_ms", "2000",     "connection_queue",  "64",
                                   "enable_keep_alive",  "no"};
  try {
    exposer_ = std::make_unique<prometheus::Exposer>(std::move(options));
  } catch (const std::exception&) {
    // civetweb only says "null context when constructing CivetServer".
    throw Error(ErrorCode::kIo, "cannot serve /metrics on " + listen +
                                    " (--metrics-listen): the port is taken, or the address is not one of this "
                                    "machine's (give another, or an empty one to serve no metrics)");
  }
  exposer_->RegisterCollectable(registry_);
  exposer_->RegisterCollectable(process_);
}

void Metrics::recordRequest(const std::string& rpc, grpc::StatusCode code, double seconds) {
  requests_.Add({{"rpc", rpc}, {"code", statusCodeName(code)}}).Increment();
  request_seconds_.Add({{"rpc", rpc}}, latencyBuckets()).Observe(seconds);
}

void Metrics::recordStages(const StageTimings& timings) {
  for (const auto& [stage, ms] : timings.stages) {
    stage_seconds_.Add({{"stage", stage}}, latencyBuckets()).Observe(ms / 1000.0);
  }
}

}  // namespace ism::server
