/* Exported batch.h functions (see api_batch.h). */
#include "api_batch.h"
#include "batch.h"

long st_batch_nfig(void) { return NFIG; }
long st_batch_nsnap(void) { return NSNAP; }
long st_batch_naux(void) { return NAUX; }

int st_variant_run(double *x, long nx, const double *P, long n_par, Tab T, double dt, long n_steps, long sub,
                   double *fig, double *snap)
{
    return variant_run(x, nx, P, n_par, T, dt, n_steps, sub, fig, snap);
}

int st_variant_share(double *X, long nx, const double *P, long n_par, const double *T3, long t_rows, long t_n,
                     const int64_t *tix, double dt, long n_steps, long sub, double *figs, double *snaps, long v0,
                     long v1)
{
    return variant_share(X, nx, P, n_par, T3, t_rows, t_n, tix, dt, n_steps, sub, figs, snaps, v0, v1);
}

void st_jacobians(const double *X, long n_rows, long n_states, const double *times, const double *irefs,
                  const double *P, long n_par, const double *T3, long t_rows, long t_n, const int64_t *tix,
                  const int64_t *vix, double *out, double *scratch)
{
    jacobians(X, n_rows, n_states, times, irefs, P, n_par, T3, t_rows, t_n, tix, vix, out, scratch);
}
