/* What every kernel header shares: the layout, the math library, the tables' type.

   The kernels are C99. Each concern is one header of static inline functions (what it computes,
   and where its equations are, in its first comment); an api_<concern>.c file includes the headers
   it needs and exports the entry points the extension module calls (declared in
   api_<concern>.h, wrapped in wrap_<concern>.pxi). The layout's constants are macros
   (layout.h, generated from servo_toolkit/sim/layout.py): no identifier in a kernel may take a
   layout constant's name. */
#ifndef SERVO_COMMON_H
#define SERVO_COMMON_H

#include <math.h>
#include <stddef.h>
#include "layout.h"

/* The stroke tables: rows of n values (T[row, k] in the Python layout), row-major (tab.h). */
#include "tab.h"

#define TAB(T, row, k) ((T).v[(long)(row) * (T).n + (long)(k)])
/* a slot that holds an index or a count (int(P[...]) in the Python layout) */
#define IX(value) ((long)(value))

/* a function the fixed-step loop inlines, so its state stays in registers; every other caller
   calls its out-of-line copy */
#if defined(__GNUC__) || defined(__clang__)
#define ST_ALWAYS_INLINE static inline __attribute__((always_inline))
#define ST_NOINLINE static __attribute__((noinline))
#define ST_FLATTEN __attribute__((flatten))
#elif defined(_MSC_VER)
#define ST_ALWAYS_INLINE static __forceinline
#define ST_NOINLINE static __declspec(noinline)
#define ST_FLATTEN
#else
#define ST_ALWAYS_INLINE static inline
#define ST_NOINLINE static
#define ST_FLATTEN
#endif

static inline double dmin(double a, double b) { return a < b ? a : b; }
static inline double dmax(double a, double b) { return a > b ? a : b; }

#endif
