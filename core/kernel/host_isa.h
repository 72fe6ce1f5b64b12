// Host-only (outside nvcc), beside the host traversal that first needed it.
// The host's instruction sets beyond the x86-64 baseline the build targets:
// hot loops compiled a second time for AVX2 (without FMA: a contraction
// would change a product's rounding, and both copies must give the same
// bits) and picked at start-up where the CPU has it. TANDEM_HOST_ISA=sse2
// in the environment keeps the baseline copies (tests run both).
#pragma once

#include "core/kernel/defines.h"

#include <cstdlib>
#include <cstring>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define TANDEM_HOST_AVX2 1
#define TANDEM_TARGET_AVX2 __attribute__((target("avx2")))
#else
#define TANDEM_HOST_AVX2 0
#endif

namespace tandem {
TANDEM_KERNEL_BEGIN

// Whether the AVX2 copies may run: the CPU has AVX2 and TANDEM_HOST_ISA is
// not "sse2". Read the environment once, at start-up, not per call.
inline bool host_cpu_has_avx2() {
#if TANDEM_HOST_AVX2
  __builtin_cpu_init();
  if (!__builtin_cpu_supports("avx2")) return false;
  const char* v = std::getenv("TANDEM_HOST_ISA");
  return v == nullptr || std::strcmp(v, "sse2") != 0;
#else
  return false;
#endif
}

TANDEM_KERNEL_END
}  // namespace tandem
