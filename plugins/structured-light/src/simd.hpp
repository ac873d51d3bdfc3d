// SPDX-License-Identifier: MIT
// x86 SIMD intrinsics for the kernel files (binarize.cpp, decode.cpp,
// vote.cpp): defines PROCAM_SL_X86 where <immintrin.h> is available. Kernels
// are compiled per function with __attribute__((target(...))) and chosen at
// run time (__builtin_cpu_supports); every one has a scalar twin giving
// bit-identical results (kernels_test.cpp). Include only from .cpp files.
#pragma once

#if defined(__x86_64__) || defined(__i386__)
// GCC 12 reports its own AVX-512 intrinsics' _mm512_undefined_* operands as
// maybe-uninitialized (a false positive, reported at the header's lines).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <immintrin.h>
#define PROCAM_SL_X86 1
#endif
