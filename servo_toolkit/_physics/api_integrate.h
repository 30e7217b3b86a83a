/* Entry points of integrate.h for the extension module: the fixed-step loops, whole (the
   Python driver servo_toolkit.sim.integrators.integrate calls them chunk by chunk). */
#ifndef SERVO_API_INTEGRATE_H
#define SERVO_API_INTEGRATE_H

#include "tab.h"

/* The sizes the loops' arrays must have: NFIG, NSNAP, NAUX, NCARRY (in that order). */
void st_integrate_dims(long dims[4]);

/* Classical RK4 (integrate.h, rk4): steps first .. last - 1 of n_steps. out_x rows of nx,
   out_aux rows of NAUX, snap NSNAP rows of nx + 2, K 5 rows of nx, PW 4 rows of pw_stride.
   Writes (status, step, n_rec, max_tau, iref) to the last five arguments. */
void st_rk4(double *x, long nx, const double *P, long n_par, Tab T, double t0, double dt, long first, long last,
            long n_steps, long sub, double iref, long rec_every, double *out_t, double *out_x, double *out_aux,
            double *fig, double *snap, double *carry, double *K, double *work, double *x0, double *PW,
            long pw_stride, long *status, long *step, long *n_rec, double *max_tau, double *iref_out);

/* The paper's scheme (integrate.h, paper); scratch: 5 nx + max(nx, 1) doubles. */
void st_paper(double *x, long nx, const double *P, Tab T, double t0, double dt, long first, long last,
              long n_steps, long sub, double iref, int paper_scheme, long rec_every, double *out_t, double *out_x,
              double *out_aux, double *carry, double *scratch, long *status, long *step, long *n_rec,
              double *max_tau, double *iref_out);

#endif
