/* Exported integrate.h loops (see api_integrate.h). */
#include "api_integrate.h"
#include "integrate.h"

void st_integrate_dims(long dims[4])
{
    dims[0] = NFIG;
    dims[1] = NSNAP;
    dims[2] = NAUX;
    dims[3] = NCARRY;
}

static void unpack(LoopResult r, long *status, long *step, long *n_rec, double *max_tau, double *iref_out)
{
    *status = r.status;
    *step = r.step;
    *n_rec = r.n_rec;
    *max_tau = r.max_tau;
    *iref_out = r.iref;
}

void st_rk4(double *x, long nx, const double *P, long n_par, Tab T, double t0, double dt, long first, long last,
            long n_steps, long sub, double iref, long rec_every, double *out_t, double *out_x, double *out_aux,
            double *fig, double *snap, double *carry, double *K, double *work, double *x0, double *PW,
            long pw_stride, long *status, long *step, long *n_rec, double *max_tau, double *iref_out)
{
    LoopResult r = rk4(x, nx, P, n_par, T, t0, dt, first, last, n_steps, sub, iref, rec_every, out_t, out_x, out_aux,
                       fig, snap, carry, K, work, x0, PW, pw_stride);
    unpack(r, status, step, n_rec, max_tau, iref_out);
}

void st_paper(double *x, long nx, const double *P, Tab T, double t0, double dt, long first, long last,
              long n_steps, long sub, double iref, int paper_scheme, long rec_every, double *out_t, double *out_x,
              double *out_aux, double *carry, double *scratch, long *status, long *step, long *n_rec,
              double *max_tau, double *iref_out)
{
    LoopResult r = paper(x, nx, P, T, t0, dt, first, last, n_steps, sub, iref, paper_scheme, rec_every, out_t, out_x,
                         out_aux, carry, scratch);
    unpack(r, status, step, n_rec, max_tau, iref_out);
}
