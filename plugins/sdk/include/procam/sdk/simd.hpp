// SPDX-License-Identifier: MIT
// Run-time SIMD dispatch for per-pixel kernels: PROCAM_SDK_X86 is defined where
// <immintrin.h> is available, and cpu_has_avx2() / cpu_has_avx512() say what
// the running CPU supports. Kernels are compiled per function with
// __attribute__((target("avx2"))) etc. (no -march flags) and chosen at run
// time with these checks; every SIMD kernel should have a scalar twin that
// gives bit-identical results, tested against it.
// Include only from .cpp files (it pulls in <immintrin.h>).
// Thread-safety: the checks are computed once (function-local statics) and
// may be called from any thread.
#pragma once

#if defined(__x86_64__) || defined(__i386__)
// GCC 12 reports its own AVX-512 intrinsics' _mm512_undefined_* operands as
// maybe-uninitialized (a false positive, reported at the header's lines).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <immintrin.h>
#define PROCAM_SDK_X86 1
#endif

namespace procam::sdk {

// AVX2 instructions can run on this CPU (false off x86).
inline bool cpu_has_avx2() noexcept {
#ifdef PROCAM_SDK_X86
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
#else
  return false;
#endif
}

// AVX-512 F + BW + VL (the byte/word kernels' subset) and AVX2 can run here.
inline bool cpu_has_avx512() noexcept {
#ifdef PROCAM_SDK_X86
  static const bool has = [] {
    __builtin_cpu_init();
    return cpu_has_avx2() && __builtin_cpu_supports("avx512f") != 0 &&
           __builtin_cpu_supports("avx512bw") != 0 && __builtin_cpu_supports("avx512vl") != 0;
  }();
  return has;
#else
  return false;
#endif
}

}  // namespace procam::sdk
