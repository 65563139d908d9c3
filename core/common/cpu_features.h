#pragma once
// Run-time CPU features for the kernels compiled twice or three times (a baseline x86-64 build and
// __attribute__((target(...))) ones): the SHOT histogram and the codebook distances. Chosen at
// run time rather than with target_clones, whose ifunc resolver runs before ThreadSanitizer's
// runtime is initialised and crashes instrumented binaries.

// Whether this compiler and architecture can build the x86 AVX2 / AVX-512 variants at all.
#if defined(__x86_64__) && defined(__GNUC__)
#define ISM_X86_KERNELS 1
#else
#define ISM_X86_KERNELS 0
#endif

namespace ism {

inline bool cpuHasAvx2() {
#if ISM_X86_KERNELS
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
#else
  return false;
#endif
}

inline bool cpuHasAvx512f() {
#if ISM_X86_KERNELS
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") != 0;
  }();
  return has;
#else
  return false;
#endif
}

}  // namespace ism
