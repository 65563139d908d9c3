#include "server/recognizer_service.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <type_traits>

#include "core/common/error.h"
#include "server/frame_stream.h"
#include "server/status_mapping.h"
#include "server/untrusted_text.h"

namespace ism::server {
// A call counted as open until gRPC is done with it (its status sent): a shutdown that waits for
// no call to be open exits with every answer delivered.
template <typename Reactor>
class RecognizerService::Counted : public Reactor {
 public:
  explicit Counted(RecognizerService& service) : service_(service) {
    ++service_.open_calls_;
    service_.context_.metrics.callOpened();
  }
  void OnDone() override {
    service_.touch();
    service_.context_.metrics.callClosed();
    --service_.open_calls_;
    delete this;
  }

 private:
  RecognizerService& service_;
};

class RecognizerService::UnaryCall final : public Counted<grpc::ServerUnaryReactor> {
 public:
  using Counted::Counted;
};

// A stream refused before it started: ends at once with the reason.
class RecognizerService::RejectedStream final
    : public Counted<grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>> {
 public:
  RejectedStream(RecognizerService& service, const grpc::Status& status) : Counted(service) { Finish(status); }
};

RecognizerService::RecognizerService(ServiceContext context, AccessControl& access)
    : context_(context), access_(access) {
  context_.abandoned = &abandoned_;
}

void RecognizerService::modelsChanged() {
  context_.metrics.setLoadedModels(context_.models.size());
  context_.health.setModels(context_.models.size());
}

void RecognizerService::touch() {
  last_call_ = std::chrono::steady_clock::now().time_since_epoch().count();
}

template <typename Request, typename Response, typename Work>
grpc::ServerUnaryReactor* RecognizerService::unary(grpc::CallbackServerContext* context, const char* rpc,
                                                   Access needed, RunsOn runs_on, const Raw* request_bytes,
                                                   Raw* response_bytes, Work work) {
  auto* reactor = new UnaryCall(*this);  // deletes itself in OnDone
  touch();
  if (shutting_down_) {
    finish(context, reactor, rpc, requestId(""), refusedWhileShuttingDown(), 0);
    return reactor;
  }
  // Refused before queueing and decoding: callers without a valid token never take a worker's time.
  if (grpc::Status denied = access_.authorize(*context, rpc, needed); !denied.ok()) {
    finish(context, reactor, rpc, requestId(""), denied, 0);
    return reactor;
  }
  auto call = [this, context, reactor, rpc, needed, request_bytes, response_bytes, work = std::move(work)]() mutable {
    const auto start = std::chrono::steady_clock::now();
    grpc::Status status;
    std::string request_id;
    try {
      // First: a call whose caller gave up is answered as such, never as bad input. That includes
      // a call handed over with no message at all (not an empty one): it ended before its request
      // came, as when its deadline passed before the server read it, and the cancellation can
      // reach this context a moment after the missing request does.
      const ShouldStop stopped = context_.stopper(context);
      throwIfStopped(stopped, rpc);
      if (!request_bytes->Valid()) {
        throw Error(ErrorCode::kCancelled, std::string(rpc) + ": the caller closed the call before sending its request");
      }
      Request request;
      decodeMessage(*request_bytes, std::string(rpc) + ": the request", &request);
      if constexpr (std::is_same_v<Request, v1::RecognizeRequest>) request_id = request.request_id();
      request_id = requestId(request_id);
      Response response;
      work(request, &response, request_id);
      // An answer nobody waits for any more is counted as what it is (a change to the models
      // has happened, though: it is reported as done).
      if (needed != Access::kAdmin) throwIfStopped(stopped, rpc);
      encodeMessage(response, response_bytes);
    } catch (...) {
      status = context_.whyStopped(context, statusFromCurrentException());
    }
    if (request_id.empty()) request_id = requestId("");
    finish(context, reactor, rpc, request_id, status,
           std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  };
  switch (runs_on) {
    case RunsOn::kCallbackThread:
      call();
      break;
    case RunsOn::kWorkers: {
      // Refused before it waits in memory for a worker (see admission.h).
      std::unique_ptr<Admission::Ticket> ticket;
      if (grpc::Status refused = context_.admission.admit(request_bytes->Length(), "this request", &ticket);
          !refused.ok()) {
        finish(context, reactor, rpc, requestId(""), refused, 0);
        break;
      }
      // shared: the pool's tasks are copyable std::functions.
      context_.pool.submit(
          [call = std::move(call), held = std::shared_ptr<Admission::Ticket>(std::move(ticket))]() mutable {
            call();
            held.reset();  // at once, not when the pool drops the task
          });
      break;
    }
    case RunsOn::kAdminThread:
      context_.admin_pool.submit(std::move(call));
      break;
  }
  return reactor;
}

void RecognizerService::beginShutdown() {
  shutting_down_ = true;
  streams_.shutDown();
}

void RecognizerService::abandonRunning() { abandoned_ = true; }

size_t RecognizerService::openCalls() const { return open_calls_ + streams_.size(); }

bool RecognizerService::idle(std::chrono::milliseconds quiet) const {
  const auto last = std::chrono::steady_clock::time_point(std::chrono::steady_clock::duration(last_call_.load()));
  return openCalls() == 0 && std::chrono::steady_clock::now() - last >= quiet;
}

void RecognizerService::finish(grpc::CallbackServerContext* context, grpc::ServerUnaryReactor* reactor,
                               const char* rpc, const std::string& request_id, const grpc::Status& status,
                               double seconds) {
  context_.metrics.recordRequest(rpc, status.error_code(), seconds);
  if (!status.ok()) {
    spdlog::warn("[{}] {} from {} failed after {:.1f}ms: {}: {}", loggable(request_id), rpc,
                 loggable(context->peer()), seconds * 1000, statusCodeName(status.error_code()),
                 loggable(status.error_message(), kMaxStatusMessage));
  }
  reactor->Finish(status);
}

grpc::ServerUnaryReactor* RecognizerService::Recognize(grpc::CallbackServerContext* context, const Raw* request,
                                                       Raw* response) {
  return unary<v1::RecognizeRequest, v1::RecognizeResponse>(
      context, "Recognize", Access::kUser, RunsOn::kWorkers, request, response,
      [this, context](const v1::RecognizeRequest& request, v1::RecognizeResponse* response,
                      const std::string& request_id) {
        if (!request.has_scene()) throw Error(ErrorCode::kInvalidInput, "Recognize: no scene given");
        response->set_request_id(request_id);
        context_.recognize(request_id, request.scene(), request.options(), context_.stopper(context),
                           response->mutable_result());
      });
}

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* RecognizerService::StreamFrames(
    grpc::CallbackServerContext* context) {
  touch();
  std::unique_ptr<StreamSlot> slot;
  if (grpc::Status denied = access_.openStream(*context, &slot); !denied.ok()) {
    context_.metrics.recordRequest("StreamFrames", denied.error_code(), 0);
    spdlog::warn("StreamFrames from {} refused: {}: {}", loggable(context->peer()), statusCodeName(denied.error_code()),
                 loggable(denied.error_message(), kMaxStatusMessage));
    return new RejectedStream(*this, denied);  // deletes itself in OnDone
  }
  return new FrameStream(context_, context, std::move(slot), streams_);  // deletes itself in OnDone
}

grpc::ServerUnaryReactor* RecognizerService::ListModels(grpc::CallbackServerContext* context, const Raw* request,
                                                        Raw* response) {
  return unary<v1::ListModelsRequest, v1::ListModelsResponse>(
      context, "ListModels", Access::kUser, RunsOn::kCallbackThread, request, response,
      [this](const v1::ListModelsRequest&, v1::ListModelsResponse* response, const std::string&) {
        for (const auto& model : context_.models.list()) *response->add_models() = model->info;
      });
}

grpc::ServerUnaryReactor* RecognizerService::GetModel(grpc::CallbackServerContext* context, const Raw* request,
                                                      Raw* response) {
  return unary<v1::GetModelRequest, v1::ModelInfo>(
      context, "GetModel", Access::kUser, RunsOn::kCallbackThread, request, response,
      [this](const v1::GetModelRequest& request, v1::ModelInfo* response, const std::string&) {
        *response = context_.models.get(request.name())->info;
      });
}

grpc::ServerUnaryReactor* RecognizerService::LoadModel(grpc::CallbackServerContext* context, const Raw* request,
                                                       Raw* response) {
  return unary<v1::LoadModelRequest, v1::ModelInfo>(
      context, "LoadModel", Access::kAdmin, RunsOn::kAdminThread, request, response,
      [this](const v1::LoadModelRequest& request, v1::ModelInfo* response, const std::string& request_id) {
        if (request.name().empty()) throw Error(ErrorCode::kInvalidInput, "LoadModel: name is empty");
        if (request.path().empty()) throw Error(ErrorCode::kInvalidInput, "LoadModel: path is empty");
        *response = context_.models.load(request.name(), request.path())->info;
        modelsChanged();
        spdlog::info("[{}] loaded model {}@{} from {} in {:.1f}ms", loggable(request_id), response->name(),
                     response->version(), loggable(response->path()), response->load_ms());
      });
}

grpc::ServerUnaryReactor* RecognizerService::UnloadModel(grpc::CallbackServerContext* context, const Raw* request,
                                                         Raw* response) {
  return unary<v1::UnloadModelRequest, v1::UnloadModelResponse>(
      context, "UnloadModel", Access::kAdmin, RunsOn::kAdminThread, request, response,
      [this](const v1::UnloadModelRequest& request, v1::UnloadModelResponse*, const std::string& request_id) {
        if (request.name().empty()) throw Error(ErrorCode::kInvalidInput, "UnloadModel: name is empty");
        context_.models.unload(request.name());
        modelsChanged();
        spdlog::info("[{}] unloaded model {}", loggable(request_id), loggable(request.name()));
      });
}

grpc::ServerUnaryReactor* RecognizerService::ReloadModels(grpc::CallbackServerContext* context, const Raw* request,
                                                          Raw* response) {
  return unary<v1::ReloadModelsRequest, v1::ReloadModelsResponse>(
      context, "ReloadModels", Access::kAdmin, RunsOn::kAdminThread, request, response,
      [this](const v1::ReloadModelsRequest&, v1::ReloadModelsResponse* response, const std::string& request_id) {
        for (const auto& failure : context_.models.reload()) {
          auto* out = response->add_failures();
          out->set_name(failure.name);
          out->set_path(failure.path);
          out->set_message(failure.message);
          spdlog::warn("[{}] reload of {} failed: {}", loggable(request_id), loggable(failure.path),
                       loggable(failure.message, kMaxStatusMessage));
        }
        for (const auto& model : context_.models.list()) *response->add_models() = model->info;
        modelsChanged();
        spdlog::info("[{}] reloaded: {} models, {} failures", loggable(request_id), response->models_size(),
                     response->failures_size());
      });
}

}  // namespace ism::server
