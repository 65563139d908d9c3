#pragma once
// The training stages' parallel loop over scans (rendering, leave-one-out scores).
#include <exception>
#include <mutex>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace ism {

// The threads a training stage runs on: `requested`, or every core when it is 0.
inline int trainingThreads(int requested) {
#ifdef _OPENMP
  return requested > 0 ? requested : omp_get_max_threads();
#else
  (void)requested;
  return 1;
#endif
}

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
