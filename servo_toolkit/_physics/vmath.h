/* Branch-free elementary functions of the right-hand side (tanh, exp_pos and exp_neg are
   exported to Python by servo_toolkit.sim.kernel).

   The friction's smooth sign is tanh; this one is within 1 ulp of the C library's (whose own
   bound is 2 ulp; tests/test_sim_tanh.py measures both against a 50-digit reference), so a
   run does not depend on the platform's libm. */
#ifndef SERVO_VMATH_H
#define SERVO_VMATH_H

#include <stdint.h>
#include <string.h>

#include "common.h"

/* 2^n for an integer n in the normal range (-1022..1023), built from its exponent bits:
   exact, and no library call (ldexp is one) */
static inline double pow2i(int n)
{
    uint64_t bits = (uint64_t)(n + 1023) << 52;
    double v;
    memcpy(&v, &bits, sizeof v);
    return v;
}

/* |a| from which tanh(a) rounds to +-1 in double precision (1 - tanh(22) = 1.6e-19) */
#define TANH_ONE 22.0
/* below this |a| the rational form, above it 1 - 2 / (exp(2 |a|) + 1) */
#define TANH_SMALL 0.625

/* exp(r) - 1 by its Taylor polynomial to r^13 (|r| <= ln 2 / 2: truncation below 1e-17) */
static inline double expm1_reduced(double r)
{
    double p = 1.0 / 6227020800.0;
    p = p * r + 1.0 / 479001600.0;
    p = p * r + 1.0 / 39916800.0;
    p = p * r + 1.0 / 3628800.0;
    p = p * r + 1.0 / 362880.0;
    p = p * r + 1.0 / 40320.0;
    p = p * r + 1.0 / 5040.0;
    p = p * r + 1.0 / 720.0;
    p = p * r + 1.0 / 120.0;
    p = p * r + 1.0 / 24.0;
    p = p * r + 1.0 / 6.0;
    p = p * r + 0.5;
    return p * r * r + r; /* added to 1 last, to keep its low bits */
}

/* Cody-Waite split of ln 2 (the high part has trailing zero bits, so n * LN2_HI is exact) */
#define VM_LN2_HI 6.93147180369123816490e-01
#define VM_LN2_LO 1.90821492927058770002e-10
#define VM_INV_LN2 1.44269504088896338700e+00

/* The reduction's two steps must stay apart: the kernels' licence to reassociate
   (-ffast-math) would otherwise fold n LN2_HI and n LN2_LO back into one rounded product
   (up to 39 ulp off). The value passes through an empty asm statement, opaque to the
   optimizer and free at run time; a volatile copy where there is no GNU asm. */
#if defined(__GNUC__) && defined(__x86_64__)
#define VM_OPAQUE(v) __asm__("" : "+x"(v))
#elif defined(__GNUC__) && defined(__aarch64__)
#define VM_OPAQUE(v) __asm__("" : "+w"(v))
#elif defined(__GNUC__)
#define VM_OPAQUE(v) __asm__("" : "+m"(v))
#else
#define VM_OPAQUE(v)                                                                              \
    do {                                                                                          \
        volatile double opaque_ = (v);                                                            \
        (v) = opaque_;                                                                            \
    } while (0)
#endif

/* exp(y) for 0 <= y <= 2 TANH_ONE (within 1 ulp; NaN passes through): y = n ln 2 + r */
static inline double exp_pos(double y)
{
    double yc = dmin(dmax(y, 0.0), 2.0 * TANH_ONE); /* NaN: n stays in range */
    double n = (double)(long)(yc * VM_INV_LN2 + 0.5); /* floor: the argument is >= 0 (no library call) */
    double hi = y - n * VM_LN2_HI;
    VM_OPAQUE(hi);
    double r = hi - n * VM_LN2_LO;
    return (1.0 + expm1_reduced(r)) * pow2i((int)n);
}

/* exp(-y) for 0 <= y <= 2 TANH_ONE, as exp_pos with -r and 2^-n */
static inline double exp_neg(double y)
{
    double yc = dmin(dmax(y, 0.0), 2.0 * TANH_ONE);
    double n = (double)(long)(yc * VM_INV_LN2 + 0.5); /* floor: the argument is >= 0 (no library call) */
    double hi = n * VM_LN2_HI - y;
    VM_OPAQUE(hi);
    double r = hi + n * VM_LN2_LO;
    return (1.0 + expm1_reduced(r)) * pow2i(-(int)n);
}

/* Cephes' tanh rational approximation on |a| < 0.625: tanh a = a + a^3 P(a^2) / Q(a^2) */
#define VM_P0 -9.64399179425052238628e-1
#define VM_P1 -9.92877231001918586564e1
#define VM_P2 -1.61468768441708447952e3
#define VM_Q0 1.12811678491632931402e2
#define VM_Q1 2.23548839060100448583e3
#define VM_Q2 4.84406305325125486048e3

/* tanh(a) within 1 ulp of the C library's: odd exactly, NaN passes through, +-1 beyond 22 */
static inline double vtanh(double a)
{
    double x = fabs(a), y;
    if (x >= TANH_ONE)
        return copysign(1.0, a);
    if (x < TANH_SMALL) {
        double z = x * x;
        y = x + x * z * (((VM_P0 * z + VM_P1) * z + VM_P2) / (((z + VM_Q0) * z + VM_Q1) * z + VM_Q2));
    } else {
        y = 1.0 - 2.0 / (exp_pos(2.0 * x) + 1.0);
    }
    return copysign(y, a);
}

#endif
