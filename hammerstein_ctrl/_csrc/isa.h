/* The instruction set a translation unit of the vector kernels is built for (lanes.cpp, normal.cpp): meson.build
 * compiles them once per set, defining HC_ISA as 1 (x86-64 AVX2) or not at all (the platform's baseline), and each
 * build names its table after its set; table.cpp picks one at run time.  HC_BASELINE says the build is the
 * baseline's, which holds the kernels that gain nothing from wider vectors (the other sets leave them out). */
#ifndef HC_ISA_H
#define HC_ISA_H

#define HC_ISA_JOIN(a, b) a##b
#define HC_ISA_PASTE(a, b) HC_ISA_JOIN(a, b)
#if defined(HC_ISA) && HC_ISA == 1
#define HC_ISA_NAME(name) HC_ISA_PASTE(name, _avx2)
#define HC_BASELINE 0
#else
#define HC_ISA_NAME(name) HC_ISA_PASTE(name, _baseline)
#define HC_BASELINE 1
#endif

#endif
