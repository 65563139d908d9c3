#pragma once
// The server's answers on the standard gRPC health service (grpc.health.v1.Health), per service
// as the protocol describes: "" for the process (NOT_SERVING once it drains) and
// "ism.v1.FurnitureRecognizer" for whether it can take a recognition now (a model is loaded, and
// it is neither draining nor refusing requests for lack of room).
#include <grpcpp/health_check_service_interface.h>

#include <mutex>
#include <string>

namespace ism::server {

class Health {
 public:
  static const char* const kRecognizer;  // "ism.v1.FurnitureRecognizer"

  // Until then the changes are remembered; the service exists once the gRPC server is built.
  void attach(grpc::HealthCheckServiceInterface* service);

  void setModels(size_t loaded);
  void setFull(bool full);  // refusing requests for lack of room
  void setDraining();

  bool recognizerServing() const;

 private:
  void publishLocked();

  mutable std::mutex mutex_;
  grpc::HealthCheckServiceInterface* service_ = nullptr;
  size_t models_ = 0;
  bool full_ = false;
  bool draining_ = false;
};

}  // namespace ism::server
