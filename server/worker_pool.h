#pragma once
// Recognition takes tens to hundreds of milliseconds, far too long to run on gRPC's callback
// threads (which must not block), so every RPC hands its work to this fixed pool.
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace ism::server {

class WorkerPool {
 public:
  // Each worker runs one task at a time with `threads_per_task` OpenMP threads: recognition's
  // parallel stages then use threads * threads_per_task threads in all, so a pool sized to the
  // cores neither oversubscribes them under load nor leaves them idle.
  WorkerPool(int threads, int threads_per_task);
  // Runs every task already submitted, then joins.
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  void submit(std::function<void()> task);

 private:
  void run();

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> tasks_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace ism::server
