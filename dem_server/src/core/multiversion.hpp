#pragma once
// DEMFEM_CLONES: compile a hot loop for AVX-512 (x86-64-v4), AVX2 and the baseline, the
// loader picking the best the CPU has. The DEM core is built with -ffp-contract=off, so
// every clone rounds alike and results stay bitwise the same on any CPU.

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && \
    !defined(DEMFEM_NO_MULTIVERSION)
#define DEMFEM_CLONES __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#elif defined(__x86_64__) && defined(__clang__) && !defined(DEMFEM_NO_MULTIVERSION)
#define DEMFEM_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define DEMFEM_CLONES
#endif
