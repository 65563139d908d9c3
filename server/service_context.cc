#include "server/service_context.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <random>

#include "core/recognition/recognizer.h"
#include "server/untrusted_text.h"

namespace ism::server {

void ServiceContext::recognize(const std::string& request_id, const v1::Scene& scene,
                               const v1::RecognitionOptions& options, const ShouldStop& should_stop,
                               v1::RecognitionResult* out) const {
  const auto model = models.get(options.model());  // held until the end: unloads cannot touch it
  StageTimings decode_timing;
  // This thread's buffers from its previous scene, given back however this call ends.
  thread_local SceneBuffers buffers;
  Scene decoded;
  struct Recycle {
    Scene& scene;
    ~Recycle() { buffers.recycle(scene); }
  } recycle{decoded};
  RecognitionOptions core_options;
  size_t out_of_range = 0;
  {
    ScopedStage stage(&decode_timing, "decode");
    core_options = optionsFromProto(options, model->model);
    decoded = sceneFromProto(scene, limits, &buffers, should_stop);
    out_of_range = dropPointsBeyondRange(&decoded, limits.max_range_m);
  }
  core_options.should_stop = should_stop;
  RecognitionResult result = ism::recognize(model->model, decoded, core_options);
  result.timings.stages.insert(result.timings.stages.begin(), decode_timing.stages.front());
  metrics.recordStages(result.timings);
  resultToProto(result, *model, out);
  out->set_out_of_range_points(out_of_range);

  std::string stages;
  for (const auto& [name, ms] : result.timings.stages) stages += fmt::format(" {}={:.1f}ms", name, ms);
  spdlog::info("[{}] model={}@{} preset={} up={} points={} out_of_range={} keypoints={} hypotheses={} total={:.1f}ms{}",
               loggable(request_id), model->name, model->info.version(), toString(core_options.preset),
               result.gravity ? toString(result.gravity->source) : "none", result.input_points, out_of_range,
               result.keypoints, result.hypotheses.size(), result.timings.total(), stages);
}

ShouldStop ServiceContext::stopper(grpc::CallbackServerContext* context, const std::atomic<bool>* also) const {
  return [this, context, also] {
    return context->IsCancelled() || std::chrono::system_clock::now() > context->deadline() || workAbandoned() ||
           (also != nullptr && also->load());
  };
}

grpc::Status ServiceContext::whyStopped(grpc::CallbackServerContext* context, grpc::Status status) const {
  if (status.error_code() != grpc::StatusCode::CANCELLED) return status;
  if (std::chrono::system_clock::now() > context->deadline()) {
    return {grpc::StatusCode::DEADLINE_EXCEEDED, "deadline exceeded: " + status.error_message()};
  }
  if (workAbandoned() && !context->IsCancelled()) return givenUpAtShutdown();
  return status;
}

grpc::Status refusedWhileShuttingDown() {
  return {grpc::StatusCode::UNAVAILABLE,
          "the server is shutting down: send the call again (to another server, or after the restart)"};
}

grpc::Status givenUpAtShutdown() {
  return {grpc::StatusCode::UNAVAILABLE,
          "the server shut down before this call finished (its drain time was over): send the call again (to "
          "another server, or after the restart)"};
}

std::string requestId(const std::string& given) {
  if (!given.empty()) return given;
  // A random per-process prefix keeps ids from different server runs apart in merged logs.
  static const std::string prefix = fmt::format("{:06x}", std::random_device{}() & 0xffffff);
  static std::atomic<uint64_t> counter{0};
  return fmt::format("{}-{}", prefix, ++counter);
}

}  // namespace ism::server
