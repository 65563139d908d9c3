#pragma once
// ism.v1.FurnitureRecognizer on gRPC's callback API. Handlers return at once; the work runs
// on the worker pool and finishes the call from there.
#include <atomic>
#include <chrono>
#include <string>

#include "ism/v1/service.grpc.pb.h"
#include "server/auth.h"
#include "server/frame_stream.h"
#include "server/service_context.h"

namespace ism::server {

// Every method is registered raw (bytes in, bytes out) and decodes its request itself, so
// that a request protobuf cannot decode gets INVALID_ARGUMENT naming it (see decodeMessage).
using RawFurnitureRecognizer = v1::FurnitureRecognizer::WithRawCallbackMethod_Recognize<
    v1::FurnitureRecognizer::WithRawCallbackMethod_StreamFrames<
        v1::FurnitureRecognizer::WithRawCallbackMethod_ListModels<
            v1::FurnitureRecognizer::WithRawCallbackMethod_GetModel<
                v1::FurnitureRecognizer::WithRawCallbackMethod_LoadModel<
                    v1::FurnitureRecognizer::WithRawCallbackMethod_UnloadModel<
                        v1::FurnitureRecognizer::WithRawCallbackMethod_ReloadModels<
                            v1::FurnitureRecognizer::Service>>>>>>>;

class RecognizerService final : public RawFurnitureRecognizer {
 public:
  // `access` decides who may call; it must outlive every call (streams hold slots in it).
  RecognizerService(ServiceContext context, AccessControl& access);

  using Raw = grpc::ByteBuffer;
  grpc::ServerUnaryReactor* Recognize(grpc::CallbackServerContext* context, const Raw* request, Raw* response) override;
  grpc::ServerBidiReactor<Raw, Raw>* StreamFrames(grpc::CallbackServerContext* context) override;
  grpc::ServerUnaryReactor* ListModels(grpc::CallbackServerContext* context, const Raw* request,
                                       Raw* response) override;
  grpc::ServerUnaryReactor* GetModel(grpc::CallbackServerContext* context, const Raw* request, Raw* response) override;
  grpc::ServerUnaryReactor* LoadModel(grpc::CallbackServerContext* context, const Raw* request, Raw* response) override;
  grpc::ServerUnaryReactor* UnloadModel(grpc::CallbackServerContext* context, const Raw* request,
                                        Raw* response) override;
  grpc::ServerUnaryReactor* ReloadModels(grpc::CallbackServerContext* context, const Raw* request,
                                         Raw* response) override;

  // The first step of a shutdown: new calls get UNAVAILABLE and open streams end (see
  // OpenStreams::shutDown), while running calls go on.
  void beginShutdown();
  // Past the drain time: the work still running stops, and its calls end UNAVAILABLE.
  void abandonRunning();
  // Unary calls and streams gRPC is not done with yet.
  size_t openCalls() const;
  // After beginShutdown: no call open and none arrived for `quiet` (a client answered last may
  // be sending its next call right now: it should be refused here rather than find the server
  // gone).
  bool idle(std::chrono::milliseconds quiet) const;

 private:
  // Where a unary call's work runs. Recognitions take the workers; changes to the models (file
  // reads) take a thread of their own, so that they never hold up a recognition nor wait for
  // one; a lookup in the model map is quick enough for gRPC's own thread.
  enum class RunsOn { kCallbackThread, kWorkers, kAdminThread };

  // Checks the caller's token, then where `runs_on` says decodes the request, runs
  // `work(request, &response, request_id)` and encodes the response; maps what it throws,
  // records metrics, logs failures.
  template <typename Request, typename Response, typename Work>
  grpc::ServerUnaryReactor* unary(grpc::CallbackServerContext* context, const char* rpc, Access needed,
                                  RunsOn runs_on, const Raw* request_bytes, Raw* response_bytes, Work work);
  void finish(grpc::CallbackServerContext* context, grpc::ServerUnaryReactor* reactor, const char* rpc,
              const std::string& request_id, const grpc::Status& status, double seconds);

  template <typename Reactor>
  class Counted;
  class UnaryCall;
  class RejectedStream;
  void touch();  // a call arrived or ended
  void modelsChanged();

  ServiceContext context_;
  AccessControl& access_;
  OpenStreams streams_;
  std::atomic<bool> shutting_down_{false};
  std::atomic<bool> abandoned_{false};
  std::atomic<size_t> open_calls_{0};  // unary calls from their handler to their OnDone
  std::atomic<std::chrono::steady_clock::rep> last_call_{0};  // when the last call arrived or ended
};

}  // namespace ism::server
