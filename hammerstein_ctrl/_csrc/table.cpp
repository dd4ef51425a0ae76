/* The kernel table of the compiled core: every kernel by its number, the vector kernels in the instruction set this
 * processor runs best.
 *
 * The vector kernels (lanes.cpp, normal.cpp) are built once for the platform's baseline and, on x86-64, again for
 * AVX2; the module's initialisation (hc_core_init) takes AVX2's where the processor and the operating system support
 * it (CPUID and XGETBV), and the baseline's for the entries AVX2's build leaves out.  The sets give the same bits:
 * the kernels' arithmetic is elementwise IEEE operations, with no contraction into fused multiply-adds and no
 * reordered sums, whatever the width of the vectors that carry it.
 */
#include <cstdlib>
#include <cstring>

#include "hc.h"

/* meson.build defines HC_HAS_ISA_VARIANTS where it built the AVX2 variants (x86-64). */
#if defined(HC_HAS_ISA_VARIANTS) && (defined(__x86_64__) || defined(_M_X64))
#define HC_X86 1
#if defined(_MSC_VER)
#include <intrin.h>
#include <immintrin.h>
#else
#include <cpuid.h>
#endif
#endif

extern "C" {
const hc_kernel *hc_single_table(void);
const hc_kernel *hc_any_order_table(void);
const hc_kernel *hc_lanes_table_baseline(void);
const hc_kernel *hc_normal_table_baseline(void);
#ifdef HC_X86
const hc_kernel *hc_lanes_table_avx2(void);
const hc_kernel *hc_normal_table_avx2(void);
#endif
int64_t hc_coefficient_pass(const hc_arg *args);
}

namespace {

/* Entries of each family: HC_SINGLE 16 per order (hold, 3 option bits), HC_LANES 8 per order up to
 * HC_LANES_MAX_ORDER (hold, 2 option bits), HC_NORMAL 32 per order (hold, 4 option bits), HC_COEFFICIENT one,
 * HC_ANY_ORDER 4 (hold, 1 option bit). */
constexpr int64_t SINGLE_COUNT = 16 * HC_MAX_ORDER, LANES_COUNT = 8 * HC_LANES_MAX_ORDER,
                  NORMAL_COUNT = 32 * HC_MAX_ORDER;
constexpr int64_t LANES_FIRST = SINGLE_COUNT, NORMAL_FIRST = LANES_FIRST + LANES_COUNT,
                  COEFFICIENT_NUMBER = NORMAL_FIRST + NORMAL_COUNT, ANY_ORDER_FIRST = COEFFICIENT_NUMBER + 1,
                  TABLE_SIZE = ANY_ORDER_FIRST + 4;

enum Isa { BASELINE = 0, AVX2 = 1 };

#ifdef HC_X86
void cpuid(int leaf, int sub, unsigned regs[4])
{
#if defined(_MSC_VER)
    int r[4];
    __cpuidex(r, leaf, sub);
    for (int i = 0; i < 4; i++)
        regs[i] = (unsigned)r[i];
#else
    __cpuid_count(leaf, sub, regs[0], regs[1], regs[2], regs[3]);
#endif
}

unsigned long long xgetbv0(void)
{
#if defined(_MSC_VER)
    return _xgetbv(0);
#else
    unsigned lo, hi;
    __asm__ volatile("xgetbv" : "=a"(lo), "=d"(hi) : "c"(0));
    return ((unsigned long long)hi << 32) | lo;
#endif
}

/* AVX2 where the processor has it and the operating system saves the AVX registers. */
Isa detect(void)
{
    unsigned r[4];
    cpuid(0, 0, r);
    if (r[0] < 7)
        return BASELINE;
    cpuid(1, 0, r);
    bool osxsave = (r[2] >> 27) & 1, avx = (r[2] >> 28) & 1;
    if (!osxsave || !avx || (xgetbv0() & 0x6) != 0x6)        /* the SSE and AVX registers */
        return BASELINE;
    cpuid(7, 0, r);
    return (r[1] >> 5) & 1 ? AVX2 : BASELINE;
}
#else
Isa detect(void)
{
    return BASELINE;
}
#endif

hc_kernel entries[TABLE_SIZE];
Isa isa = BASELINE;

}  // namespace

extern "C" {

/* The entry's number by the table's layout, whether or not it is built. */
static int64_t position(int64_t family, int64_t n, int64_t hold, int64_t options)
{
    if (hold != 0 && hold != 1)
        return -1;
    switch (family) {
    case HC_SINGLE:
        return 1 <= n && n <= HC_MAX_ORDER && 0 <= options && options < 8 ? (n - 1) * 16 + hold * 8 + options : -1;
    case HC_LANES:
        return 1 <= n && n <= HC_LANES_MAX_ORDER && 0 <= options && options < 4
                   ? LANES_FIRST + (n - 1) * 8 + hold * 4 + options
                   : -1;
    case HC_NORMAL:
        return 1 <= n && n <= HC_MAX_ORDER && 0 <= options && options < 16
                   ? NORMAL_FIRST + (n - 1) * 32 + hold * 16 + options
                   : -1;
    case HC_COEFFICIENT:
        return COEFFICIENT_NUMBER;
    case HC_ANY_ORDER:
        return 0 <= options && options < 2 ? ANY_ORDER_FIRST + hold * 2 + options : -1;
    default:
        return -1;
    }
}

int64_t hc_kernel_number(int64_t family, int64_t n, int64_t hold, int64_t options)
{
    int64_t number = position(family, n, hold, options);
    return number >= 0 && entries[number] != nullptr ? number : -1;
}

void hc_core_init(void)
{
    /* $HAMMERSTEIN_CTRL_VECTOR_ISA=baseline keeps the baseline's vector kernels (to compare the sets' bits) */
    const char *asked = std::getenv("HAMMERSTEIN_CTRL_VECTOR_ISA");
    isa = asked != nullptr && std::strcmp(asked, "baseline") == 0 ? BASELINE : detect();
    const hc_kernel *single = hc_single_table(), *lanes = hc_lanes_table_baseline(),
                    *normal = hc_normal_table_baseline(), *wide_lanes = lanes, *wide_normal = normal;
#ifdef HC_X86
    if (isa == AVX2) {
        wide_lanes = hc_lanes_table_avx2();
        wide_normal = hc_normal_table_avx2();
    }
#endif
    for (int64_t i = 0; i < SINGLE_COUNT; i++)
        entries[i] = single[i];
    for (int64_t i = 0; i < LANES_COUNT; i++)
        entries[LANES_FIRST + i] = wide_lanes[i] ? wide_lanes[i] : lanes[i];
    for (int64_t i = 0; i < NORMAL_COUNT; i++)
        entries[NORMAL_FIRST + i] = wide_normal[i] ? wide_normal[i] : normal[i];
    entries[COEFFICIENT_NUMBER] = hc_coefficient_pass;
    for (int64_t i = 0; i < 4; i++)
        entries[ANY_ORDER_FIRST + i] = hc_any_order_table()[i];
}

hc_kernel hc_kernel_at(int64_t number)
{
    return 0 <= number && number < TABLE_SIZE ? entries[number] : nullptr;
}

const char *hc_vector_isa(void)
{
    static const char *const names[] = {"baseline", "avx2"};
    return names[isa];
}

}  // extern "C"
