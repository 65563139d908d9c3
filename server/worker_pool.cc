#include "server/worker_pool.h"

#include <algorithm>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace ism::server {

WorkerPool::WorkerPool(int threads, int threads_per_task) {
  for (int i = 0; i < std::max(1, threads); ++i) {
    threads_.emplace_back([this, threads_per_task] {
#ifdef _OPENMP
      // OpenMP's thread count is per thread: this sets it for the regions this worker starts.
      omp_set_num_threads(std::max(1, threads_per_task));
#endif
      run();
    });
  }
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  for (auto& thread : threads_) thread.join();
}

void WorkerPool::submit(std::function<void()> task) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    tasks_.push_back(std::move(task));
  }
  wake_.notify_one();
}

void WorkerPool::run() {
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !tasks_.empty(); });
      if (tasks_.empty()) return;  // stopping and drained
      task = std::move(tasks_.front());
      tasks_.pop_front();
    }
    task();
  }
}

}  // namespace ism::server
