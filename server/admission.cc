#include "server/admission.h"

#include <malloc.h>

#include <spdlog/fmt/fmt.h>

namespace ism::server {
namespace {

// Below this a burst leaves little to hand back, and trimming is not worth its time.
constexpr size_t kTrimAfter = size_t{64} << 20;

double mb(size_t bytes) { return static_cast<double>(bytes) / (1 << 20); }

}  // namespace

Admission::Admission(size_t max_bytes, Health* health) : max_bytes_(max_bytes), health_(health) {}

Admission::Ticket::~Ticket() { owner_.release(bytes_); }

grpc::Status Admission::admit(size_t bytes, const char* what, std::unique_ptr<Ticket>* ticket) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (max_bytes_ > 0 && bytes > max_bytes_) {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED,
            fmt::format("{} of {:.1f} MB is larger than the {:.1f} MB of requests this server holds at once "
                        "(--max-queued-mb): send a smaller scene",
                        what, mb(bytes), mb(max_bytes_))};
  }
  if (max_bytes_ > 0 && held_ + bytes > max_bytes_) {
    if (!full_ && health_ != nullptr) health_->setFull(true);
    full_ = true;
    return {grpc::StatusCode::RESOURCE_EXHAUSTED,
            fmt::format("the server is full: it holds {:.1f} MB of requests and takes {:.1f} MB at once "
                        "(--max-queued-mb); {} of {:.1f} MB does not fit: send it again later, or to another server",
                        mb(held_), mb(max_bytes_), what, mb(bytes))};
  }
  held_ += bytes;
  peak_since_trim_ = std::max(peak_since_trim_, held_);
  ticket->reset(new Ticket(*this, bytes));
  return grpc::Status::OK;
}

void Admission::release(size_t bytes) {
  bool trim = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    held_ -= bytes;
    // Half the bound: a server that just refused is not told it serves again for a moment's room.
    if (full_ && held_ <= max_bytes_ / 2) {
      full_ = false;
      if (health_ != nullptr) health_->setFull(false);
    }
    if (held_ == 0 && peak_since_trim_ >= kTrimAfter) {
      peak_since_trim_ = 0;
      trim = true;
    }
  }
  // The free pages of every arena go back to the kernel, not only those at the heap's top that
  // M_TRIM_THRESHOLD (main.cc) would give back: idle RSS after a burst is the idle server's.
  if (trim) malloc_trim(0);
}

size_t Admission::held() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return held_;
}

}  // namespace ism::server
