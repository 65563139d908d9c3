#pragma once
// Admission control: the bytes of the requests the server has taken and not yet answered
// (queued for a worker or being recognised) are bounded. A request that does not fit is
// refused at once with RESOURCE_EXHAUSTED instead of waiting in memory: 30 requests of 48 MB
// queued behind two workers held 2.7 GB, and the server stopped answering anything.
// While it refuses, the recognizer's health is NOT_SERVING, so load balancers send elsewhere;
// it serves again once what it holds is down to half the bound. When the last request of a
// burst is done, the memory the burst used is handed back to the kernel.
// Unary Recognize calls count from arrival; stream frames while they are recognised (a stream
// queues at most FrameStream::kMaxQueuedFrames more).
#include <grpcpp/support/status.h>

#include <cstddef>
#include <memory>
#include <mutex>

#include "server/health.h"

namespace ism::server {

class Admission {
 public:
  // Room held by one admitted request, given back when it is destroyed.
  class Ticket {
   public:
    ~Ticket();
    Ticket(const Ticket&) = delete;
    Ticket& operator=(const Ticket&) = delete;

   private:
    friend class Admission;
    Ticket(Admission& owner, size_t bytes) : owner_(owner), bytes_(bytes) {}
    Admission& owner_;
    size_t bytes_;
  };

  // `max_bytes` 0: no bound. `health` (may be null) hears when the server is full.
  Admission(size_t max_bytes, Health* health);

  // A ticket for a request of `bytes`, or RESOURCE_EXHAUSTED saying why (`what` names the
  // request in the message).
  grpc::Status admit(size_t bytes, const char* what, std::unique_ptr<Ticket>* ticket);

  size_t held() const;
  size_t maxBytes() const { return max_bytes_; }

 private:
  void release(size_t bytes);

  const size_t max_bytes_;
  Health* health_;
  mutable std::mutex mutex_;
  size_t held_ = 0;
  size_t peak_since_trim_ = 0;
  bool full_ = false;
};

}  // namespace ism::server
