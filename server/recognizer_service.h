#pragma once
// ism.v1.FurnitureRecognizer on gRPC's callback API. Handlers return at once; the work runs
// on the worker pool and finishes the call from there.
#include <string>

#include "ism/v1/service.grpc.pb.h"
#include "server/auth.h"
#include "server/service_context.h"

namespace ism::server {

class RecognizerService final : public v1::FurnitureRecognizer::CallbackService {
 public:
  // `access` decides who may call; it must outlive every call (streams hold slots in it).
  RecognizerService(ServiceContext context, AccessControl& access) : context_(context), access_(access) {}

  grpc::ServerUnaryReactor* Recognize(grpc::CallbackServerContext* context, const v1::RecognizeRequest* request,
                                      v1::RecognizeResponse* response) override;
  grpc::ServerBidiReactor<v1::StreamFramesRequest, v1::FrameResult>* StreamFrames(
      grpc::CallbackServerContext* context) override;
  grpc::ServerUnaryReactor* ListModels(grpc::CallbackServerContext* context, const v1::ListModelsRequest* request,
                                       v1::ListModelsResponse* response) override;
  grpc::ServerUnaryReactor* GetModel(grpc::CallbackServerContext* context, const v1::GetModelRequest* request,
                                     v1::ModelInfo* response) override;
  grpc::ServerUnaryReactor* LoadModel(grpc::CallbackServerContext* context, const v1::LoadModelRequest* request,
                                      v1::ModelInfo* response) override;
  grpc::ServerUnaryReactor* UnloadModel(grpc::CallbackServerContext* context, const v1::UnloadModelRequest* request,
                                        v1::UnloadModelResponse* response) override;
  grpc::ServerUnaryReactor* ReloadModels(grpc::CallbackServerContext* context,
                                         const v1::ReloadModelsRequest* request,
                                         v1::ReloadModelsResponse* response) override;

 private:
  // Checks the caller's token, then runs `work(request_id)` on the pool, maps what it throws,
  // records metrics, logs failures.
  template <typename Work>
  grpc::ServerUnaryReactor* unary(grpc::CallbackServerContext* context, const char* rpc, Access needed,
                                  const std::string& given_request_id, Work work);
  void finish(grpc::CallbackServerContext* context, grpc::ServerUnaryReactor* reactor, const char* rpc,
              const std::string& request_id, const grpc::Status& status, double seconds);

  ServiceContext context_;
  AccessControl& access_;
};

}  // namespace ism::server
