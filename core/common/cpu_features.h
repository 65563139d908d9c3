#pragma once
// Run-time CPU features for the kernels compiled twice or three times (a portable build and
// __attribute__((target(...))) x86 ones): the SHOT histogram and the codebook distances. Chosen
// at run time rather than with target_clones, whose ifunc resolver runs before ThreadSanitizer's
// runtime is initialised and crashes instrumented binaries.
//
// ISM_PORTABLE_KERNELS=1 in the environment makes every kernel take its portable path, the one
// an x86 CPU without AVX2 or an arm64 one runs, so that path is tested on the machines that
// would otherwise never run it (ctest label `portable`).
#include <cstdio>
#include <cstdlib>
#include <cstring>

// Whether this compiler and architecture can build the x86 AVX2 / AVX-512 variants at all. The
// CMake option ISM_X86_KERNELS=OFF leaves them out, as a build for another architecture does.
#ifndef ISM_X86_KERNELS
#if defined(__x86_64__) && defined(__GNUC__)
#define ISM_X86_KERNELS 1
#else
#define ISM_X86_KERNELS 0
#endif
#endif

namespace ism {

struct CpuFeatures {
  bool avx2 = false, avx512f = false;
};

// What the kernels may use given what the CPU has and the value of ISM_PORTABLE_KERNELS
// (nullptr when unset): "1" takes everything away, "0" or "" nothing. Any other value is
// reported on stderr and taken as unset, so a typo never stops a server.
inline CpuFeatures applyPortableOverride(CpuFeatures detected, const char* portable) {
  if (portable == nullptr || std::strcmp(portable, "") == 0 || std::strcmp(portable, "0") == 0) return detected;
  if (std::strcmp(portable, "1") == 0) return CpuFeatures{};
  std::fprintf(stderr, "ISM_PORTABLE_KERNELS='%s' is neither 1 nor 0: ignored, the CPU's widest kernels are used\n",
               portable);
  return detected;
}

// Asked once per process: __builtin_cpu_supports takes only a literal feature name.
inline const CpuFeatures& cpuFeatures() {
  static const CpuFeatures features = [] {
    CpuFeatures f;
#if ISM_X86_KERNELS
    __builtin_cpu_init();
    f.avx2 = __builtin_cpu_supports("avx2") != 0;
    f.avx512f = __builtin_cpu_supports("avx512f") != 0;
#endif
    return applyPortableOverride(f, std::getenv("ISM_PORTABLE_KERNELS"));
  }();
  return features;
}

inline bool cpuHasAvx2() { return cpuFeatures().avx2; }
inline bool cpuHasAvx512f() { return cpuFeatures().avx512f; }

}  // namespace ism
