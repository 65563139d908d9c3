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

struct CpuFeatures {
  bool avx2 = false, avx512f = false;
};

// Asked once per process: __builtin_cpu_supports takes only a literal feature name.
inline const CpuFeatures& cpuFeatures() {
  static const CpuFeatures features = [] {
    CpuFeatures f;
#if ISM_X86_KERNELS
    __builtin_cpu_init();
    f.avx2 = __builtin_cpu_supports("avx2") != 0;
    f.avx512f = __builtin_cpu_supports("avx512f") != 0;
#endif
    return f;
  }();
  return features;
}

inline bool cpuHasAvx2() { return cpuFeatures().avx2; }
inline bool cpuHasAvx512f() { return cpuFeatures().avx512f; }

}  // namespace ism
