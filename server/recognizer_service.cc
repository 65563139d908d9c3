#include "server/recognizer_service.h"

#include <spdlog/spdlog.h>

#include <chrono>

#include "core/common/error.h"
#include "server/frame_stream.h"
#include "server/status_mapping.h"

namespace ism::server {
namespace {

// A stream refused before it started: ends at once with the reason.
class RejectedStream final : public grpc::ServerBidiReactor<v1::StreamFramesRequest, v1::FrameResult> {
 public:
  explicit RejectedStream(const grpc::Status& status) { Finish(status); }
  void OnDone() override { delete this; }
};

}  // namespace

template <typename Work>
grpc::ServerUnaryReactor* RecognizerService::unary(grpc::CallbackServerContext* context, const char* rpc,
                                                   Access needed, const std::string& given_request_id, Work work) {
  auto* reactor = context->DefaultReactor();
  std::string request_id = requestId(given_request_id);
  // Refused before queueing: callers without a valid token never take a worker's time.
  if (grpc::Status denied = access_.authorize(*context, rpc, needed); !denied.ok()) {
    finish(context, reactor, rpc, request_id, denied, 0);
    return reactor;
  }
  context_.pool.submit([this, context, reactor, rpc, request_id = std::move(request_id),
                        work = std::move(work)]() mutable {
    const auto start = std::chrono::steady_clock::now();
    grpc::Status status;
    try {
      // A call that waited in the queue past its deadline is not worth starting.
      throwIfStopped(callStopper(context), rpc);
      work(request_id);
    } catch (...) {
      status = withDeadlineReason(context, statusFromCurrentException());
    }
    finish(context, reactor, rpc, request_id, status,
           std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  });
  return reactor;
}

void RecognizerService::finish(grpc::CallbackServerContext* context, grpc::ServerUnaryReactor* reactor,
                               const char* rpc, const std::string& request_id, const grpc::Status& status,
                               double seconds) {
  context_.metrics.recordRequest(rpc, status.error_code(), seconds);
  if (!status.ok()) {
    spdlog::warn("[{}] {} from {} failed after {:.1f}ms: {}: {}", request_id, rpc, context->peer(), seconds * 1000,
                 statusCodeName(status.error_code()), status.error_message());
  }
  reactor->Finish(status);
}

grpc::ServerUnaryReactor* RecognizerService::Recognize(grpc::CallbackServerContext* context,
                                                       const v1::RecognizeRequest* request,
                                                       v1::RecognizeResponse* response) {
  return unary(context, "Recognize", Access::kUser, request->request_id(), [=](const std::string& request_id) {
    response->set_request_id(request_id);
    context_.recognize(request_id, request->scene(), request->options(), callStopper(context),
                       response->mutable_result());
  });
}

grpc::ServerBidiReactor<v1::StreamFramesRequest, v1::FrameResult>* RecognizerService::StreamFrames(
    grpc::CallbackServerContext* context) {
  std::unique_ptr<StreamSlot> slot;
  if (grpc::Status denied = access_.openStream(*context, &slot); !denied.ok()) {
    context_.metrics.recordRequest("StreamFrames", denied.error_code(), 0);
    spdlog::warn("StreamFrames from {} refused: {}: {}", context->peer(), statusCodeName(denied.error_code()),
                 denied.error_message());
    return new RejectedStream(denied);
  }
  return new FrameStream(context_, context, std::move(slot));  // deletes itself in OnDone
}

grpc::ServerUnaryReactor* RecognizerService::ListModels(grpc::CallbackServerContext* context,
                                                        const v1::ListModelsRequest*,
                                                        v1::ListModelsResponse* response) {
  return unary(context, "ListModels", Access::kUser, "", [=](const std::string&) {
    for (const auto& model : context_.models.list()) *response->add_models() = model->info;
  });
}

grpc::ServerUnaryReactor* RecognizerService::GetModel(grpc::CallbackServerContext* context,
                                                      const v1::GetModelRequest* request, v1::ModelInfo* response) {
  return unary(context, "GetModel", Access::kUser, "",
               [=](const std::string&) { *response = context_.models.get(request->name())->info; });
}

grpc::ServerUnaryReactor* RecognizerService::LoadModel(grpc::CallbackServerContext* context,
                                                       const v1::LoadModelRequest* request, v1::ModelInfo* response) {
  return unary(context, "LoadModel", Access::kAdmin, "", [=](const std::string& request_id) {
    if (request->name().empty()) throw Error(ErrorCode::kInvalidInput, "LoadModel: name is empty");
    if (request->path().empty()) throw Error(ErrorCode::kInvalidInput, "LoadModel: path is empty");
    *response = context_.models.load(request->name(), request->path())->info;
    context_.metrics.setLoadedModels(context_.models.size());
    spdlog::info("[{}] loaded model {}@{} from {} in {:.1f}ms", request_id, response->name(), response->version(),
                 response->path(), response->load_ms());
  });
}

grpc::ServerUnaryReactor* RecognizerService::UnloadModel(grpc::CallbackServerContext* context,
                                                         const v1::UnloadModelRequest* request,
                                                         v1::UnloadModelResponse*) {
  return unary(context, "UnloadModel", Access::kAdmin, "", [=](const std::string& request_id) {
    context_.models.unload(request->name());
    context_.metrics.setLoadedModels(context_.models.size());
    spdlog::info("[{}] unloaded model {}", request_id, request->name());
  });
}

grpc::ServerUnaryReactor* RecognizerService::ReloadModels(grpc::CallbackServerContext* context,
                                                          const v1::ReloadModelsRequest*,
                                                          v1::ReloadModelsResponse* response) {
  return unary(context, "ReloadModels", Access::kAdmin, "", [=](const std::string& request_id) {
    for (const auto& failure : context_.models.reload()) {
      auto* out = response->add_failures();
      out->set_name(failure.name);
      out->set_path(failure.path);
      out->set_message(failure.message);
      spdlog::warn("[{}] reload of {} failed: {}", request_id, failure.path, failure.message);
    }
    for (const auto& model : context_.models.list()) *response->add_models() = model->info;
    context_.metrics.setLoadedModels(context_.models.size());
    spdlog::info("[{}] reloaded: {} models, {} failures", request_id, response->models_size(),
                 response->failures_size());
  });
}

}  // namespace ism::server
