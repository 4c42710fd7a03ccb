// What the core's hot loops use beyond plain C++: SSE2 intrinsics where the target has them (all of
// x86-64), and LIDAR_DESKEW_AVX2_CLONES, which also builds a function in an AVX2 variant chosen when the
// library loads (GCC on x86-64; its "avx2" has no FMA, which would round differently: both variants
// give the same bits).
#pragma once

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define LIDAR_DESKEW_AVX2_CLONES __attribute__((target_clones("avx2", "default")))
#define LIDAR_DESKEW_HAS_AVX2_CLONES 1
#else
#define LIDAR_DESKEW_AVX2_CLONES
#endif

// GCC's generic vectors with __builtin_shufflevector (GCC 12 on; Clang): in an AVX2 clone a 4-double
// vector is one register.
#if defined(__clang__) || (defined(__GNUC__) && __GNUC__ >= 12)
#define LIDAR_DESKEW_VECTOR_SHUFFLES 1
#else
#define LIDAR_DESKEW_VECTOR_SHUFFLES 0
#endif
