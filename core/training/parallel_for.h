#pragma once
// The training stages' parallel loop over scans (rendering, leave-one-out scores).
#include <exception>
#include <mutex>

namespace ism {

// Runs body(i) for i in [0, n) on `threads` OpenMP threads; the first exception is rethrown.
template <typename F>
void parallelFor(int n, int threads, F&& body) {
  std::exception_ptr failure;
  std::mutex mutex;
#pragma omp parallel for schedule(dynamic) num_threads(threads)
  for (int i = 0; i < n; ++i) {
    try {
      body(i);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex);
      if (!failure) failure = std::current_exception();
    }
  }
  if (failure) std::rethrow_exception(failure);
}

}  // namespace ism
