#pragma once
/// MAGVINE_HOT_KERNEL: compile a hot function twice, for baseline x86-64 and for x86-64-v3 (AVX2 and FMA), and let
/// the loader pick the copy the CPU can run (GCC function multiversioning through an ifunc). `flatten` inlines
/// everything the function calls into each copy, so the whole kernel runs at the chosen level. The build itself
/// stays portable (baseline x86-64); a machine without AVX2 runs the baseline copy.
///
/// The two copies round differently in the last bits (FMA contracts a·b + c), so results may differ between machines
/// of different levels; on one machine they repeat exactly. Other compilers and architectures, and builds with the
/// CMake option MAGVINE_MULTIVERSION=OFF (which defines MAGVINE_NO_MULTIVERSION), get one plain copy: the baseline.
///
/// Use it on functions and member functions that are not templates (GCC 12 does not clone templates).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(MAGVINE_NO_MULTIVERSION)
#define MAGVINE_HOT_KERNEL __attribute__((target_clones("arch=x86-64-v3", "default"), flatten))
#else
#define MAGVINE_HOT_KERNEL
#endif
