/* Many closed-loop variants: the single run's RK4 loop for each, the variants shared among
   threads (the Python face: servo_toolkit.sim.batch and servo_toolkit.sim.batch_run).

   Every variant is a row of a parameter matrix P (n_variants, nP) built by the model code
   (sim/variants.py), with its own initial state and, where its tables differ (a rigid chain
   whose load inertia varies), its own stroke tables (T[tix[v]]). A variant runs through the
   same right-hand side (rhs_phys), controller sample (controller_sample) and RK4 stages (the
   loop rk4 of integrate.h) as a single run: one physics. Instead of traces a variant keeps
   its figures (largest |tracking error|, peak |current|, whether a limit was reached, peak
   |motor torque|) and the states where its step is checked (peak current, largest drivetrain
   deflection, the end); a non-finite state or the stroke end stops that variant only.

   The batch is every variant run by variant_run, one after another on each of the caller's
   threads (the extension module's run_variants shares the variants among worker threads,
   without the interpreter lock): a variant's numbers do not depend on the thread that ran
   it nor on its neighbours. */
#ifndef SERVO_BATCH_H
#define SERVO_BATCH_H

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include "common.h"
#include "vmath.h"
#include "api_integrate.h"
#include "api_rhs.h"

/* One variant: the single run's loop (rk4 of integrate.h), keeping its figures and
   snapshots (and two records, its start and end, which are dropped).

   x (nx states) is advanced in place; fig (NFIG) receives status (OK, NONFINITE,
   STROKE_END), steps done, max |q - r| (rad or m), max |i| (A), 1 if the current reference or
   the voltage reached its limit, max |motor torque|; snap (NSNAP rows of nx + 2) the states of
   S_PEAK, S_DEFLECTION and S_END with their time and held current reference. n_par is the
   length of P (the split step's scratch copy of it). Returns 0, or -1 when the scratch could
   not be allocated (nothing run). */
static inline int variant_run(double *x, long nx, const double *P, long n_par, Tab T, double dt, long n_steps,
                              long sub, double *fig, double *snap)
{
    long wide = n_par > nx ? n_par : nx;            /* PW: 4 rows wide enough for P and for x */
    long nw = nx > 1 ? nx : 1;
    long ns = NSNAP * (nx + 2);
    size_t total = 2 + 2 * (size_t)nx + 2 * NAUX    /* out_t, out_x, out_aux */
                   + NCARRY + 5 * (size_t)nx        /* carry, K (zeros) */
                   + (size_t)nw + (size_t)nx         /* work, x0 */
                   + 4 * (size_t)wide               /* PW */
                   + (size_t)nx + NFIG + (size_t)ns; /* the variant's own state, figures, snapshots */
    double *buf = (double *)calloc(total, sizeof(double));
    if (!buf)
        return -1;
    double *out_t = buf;
    double *out_x = out_t + 2;
    double *out_aux = out_x + 2 * nx;
    double *carry = out_aux + 2 * NAUX;
    double *K = carry + NCARRY;
    double *work = K + 5 * nx;
    double *x0 = work + nw;
    double *PW = x0 + nx;
    /* the loop writes its state, figures and snapshots in a buffer of its own and they are
       copied out at the end: rows of neighbouring variants share cache lines, which threads
       running them side by side would otherwise pass back and forth at every sample */
    double *xv = PW + 4 * wide;
    double *figv = xv + nx;
    double *snapv = figv + NFIG;
    memcpy(xv, x, (size_t)nx * sizeof *x);
    memcpy(figv, fig, NFIG * sizeof *fig);
    memcpy(snapv, snap, (size_t)ns * sizeof *snap);
    /* the loop's result is in fig too; the single run's compiled loop itself (st_rk4, not a
       copy inlined here), so a variant equals its single run to the last bit */
    long status, step, n_rec;
    double max_tau, iref_end;
    st_rk4(xv, nx, P, n_par, T, 0.0, dt, 0, n_steps, n_steps, sub, 0.0, n_steps + 1, out_t, out_x, out_aux, figv,
           snapv, carry, K, work, x0, PW, wide, &status, &step, &n_rec, &max_tau, &iref_end);
    memcpy(x, xv, (size_t)nx * sizeof *x);
    memcpy(fig, figv, NFIG * sizeof *fig);
    memcpy(snap, snapv, (size_t)ns * sizeof *snap);
    free(buf);
    return 0;
}

/* variant_run for the variants v0 .. v1 - 1 of a batch: rows of X (nx), P (n_par), figs
   (NFIG), snaps (NSNAP x (nx + 2)); variant v reads the tables T3[tix[v]] (t_rows x t_n each).
   Returns 0, or -1 when a variant's scratch could not be allocated (that variant and the
   ones after it not run). */
static inline int variant_share(double *X, long nx, const double *P, long n_par, const double *T3, long t_rows,
                                long t_n, const int64_t *tix, double dt, long n_steps, long sub, double *figs,
                                double *snaps, long v0, long v1)
{
    for (long v = v0; v < v1; v++) {
        Tab tv;
        tv.v = T3 + (long)tix[v] * t_rows * t_n;
        tv.n = t_n;
        if (variant_run(X + v * nx, nx, P + v * n_par, n_par, tv, dt, n_steps, sub, figs + v * NFIG,
                        snaps + v * NSNAP * (nx + 2)) != 0)
            return -1;
    }
    return 0;
}

/* d(rhs)/dx by central differences (steps as stability.jacobian) at the states X[m] (n_states
   each) of variants vix[m], into out[m] (n_states x n_states, out[m, k, j] = d f_k / d x_j),
   for m = 0 .. n_rows - 1: each with its time times[m], held current reference irefs[m],
   parameters P[vix[m]] (rows of n_par) and tables T3[tix[vix[m]]]. Serial: a few hundred
   right-hand sides per variant against tens of thousands in its run. scratch: 4 n_states +
   NAUX doubles. */
static inline void jacobians(const double *X, long n_rows, long n_states, const double *times, const double *irefs,
                             const double *P, long n_par, const double *T3, long t_rows, long t_n,
                             const int64_t *tix, const int64_t *vix, double *out, double *scratch)
{
    long n = n_states;
    double *f1 = scratch, *f2 = f1 + n, *xp = f2 + n, *xm = xp + n, *aux = xm + n;
    for (long m = 0; m < n_rows; m++) {
        long v = (long)vix[m];
        const double *xr = X + m * n;
        const double *pv = P + v * n_par;
        Tab tv;
        tv.v = T3 + (long)tix[v] * t_rows * t_n;
        tv.n = t_n;
        for (long j = 0; j < n; j++) {
            double h = 1e-7 * (1.0 + fabs(xr[j]));
            for (long k = 0; k < n; k++) {
                xp[k] = xr[k];
                xm[k] = xr[k];
            }
            xp[j] += h;
            xm[j] -= h;
            st_rhs(times[m], xp, n, pv, tv, irefs[m], f1, aux); /* the compiled rhs that Python calls */
            st_rhs(times[m], xm, n, pv, tv, irefs[m], f2, aux);
            for (long k = 0; k < n; k++) {
                double twice_h = 2 * h;
                VM_OPAQUE(twice_h); /* a true division each time, not a reciprocal shared by
                                       the column: the quotients of stability.jacobian */
                out[(m * n + k) * n + j] = (f1[k] - f2[k]) / twice_h;
            }
        }
    }
}

#endif
