#include "server/health.h"

#include "ism/v1/service.grpc.pb.h"

namespace ism::server {

const char* const Health::kRecognizer = v1::FurnitureRecognizer::service_full_name();

void Health::attach(grpc::HealthCheckServiceInterface* service) {
  std::lock_guard<std::mutex> lock(mutex_);
  service_ = service;
  publishLocked();
}

void Health::setModels(size_t loaded) {
  std::lock_guard<std::mutex> lock(mutex_);
  models_ = loaded;
  publishLocked();
}

void Health::setFull(bool full) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (full_ == full) return;
  full_ = full;
  publishLocked();
}

void Health::setDraining() {
  std::lock_guard<std::mutex> lock(mutex_);
  draining_ = true;
  publishLocked();
}

bool Health::recognizerServing() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return models_ > 0 && !full_ && !draining_;
}

void Health::publishLocked() {
  if (service_ == nullptr) return;
  service_->SetServingStatus("", !draining_);
  service_->SetServingStatus(kRecognizer, models_ > 0 && !full_ && !draining_);
}

}  // namespace ism::server
