/* Stroke tables (built by servo_toolkit/sim/tables.py): the cell of a position and the cubic
   Hermite interpolation of a table row, values and exact derivatives. Rows in layout.h. */
#ifndef SERVO_TABLES_H
#define SERVO_TABLES_H

#include "common.h"

/* Table cell *k and local coordinate *t in [0, 1] of q (clamped; periodic tables wrap). */
static inline void cell(const double *P, double q, long *k, double *t)
{
    double s = (q - P[TAB_LO]) * P[INV_H];
    double last = P[TAB_N] - 1.0;
    if (P[PERIODIC] > 0.0)
        s = s - last * floor(s / last);
    if (s <= 0.0) {
        *k = 0;
        *t = 0.0;
    } else if (s >= last) {
        *k = (long)last - 1;
        *t = 1.0;
    } else {
        *k = (long)s;
        *t = s - (double)*k;
    }
}

/* Cubic Hermite value *val and derivative *der of table row (row + 1 holds the derivatives)
   in cell k at local coordinate t; h is the grid step. */
static inline void interp(Tab T, long row, long k, double t, double h, double inv_h, double *val, double *der)
{
    double y0 = TAB(T, row, k), y1 = TAB(T, row, k + 1);
    double m0 = TAB(T, row + 1, k) * h, m1 = TAB(T, row + 1, k + 1) * h;
    double t2 = t * t, t3 = t2 * t;
    *val = (2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + t) * m0 + (3 * t2 - 2 * t3) * y1 + (t3 - t2) * m1;
    *der = ((6 * t2 - 6 * t) * (y0 - y1) + (3 * t2 - 4 * t + 1) * m0 + (3 * t2 - 2 * t) * m1) * inv_h;
}

/* Table row at q, value and exact derivative: the end values held outside a non-periodic
   table (derivative 0); periodic tables wrap. */
static inline void hermite(Tab T, long row, const double *P, double q, double *val, double *der)
{
    long k;
    double t;
    cell(P, q, &k, &t);
    if (P[PERIODIC] <= 0.0 && (t == 0.0 || t == 1.0) && (q <= P[TAB_LO] || (double)k == P[TAB_N] - 2)) {
        *val = TAB(T, row, k + (long)t);
        *der = 0.0;
        return;
    }
    interp(T, row, k, t, P[TAB_H], P[INV_H], val, der);
}

#endif
