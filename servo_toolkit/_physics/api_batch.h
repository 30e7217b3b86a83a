/* Entry points of batch.h (the batched variants and their Jacobians) for the extension module. */
#ifndef SERVO_API_BATCH_H
#define SERVO_API_BATCH_H

#include <stdint.h>
#include "tab.h"

/* the layout's NFIG, NSNAP and NAUX (the module does not include layout.h) */
long st_batch_nfig(void);
long st_batch_nsnap(void);
long st_batch_naux(void);

int st_variant_run(double *x, long nx, const double *P, long n_par, Tab T, double dt, long n_steps, long sub,
                   double *fig, double *snap);
int st_variant_share(double *X, long nx, const double *P, long n_par, const double *T3, long t_rows, long t_n,
                     const int64_t *tix, double dt, long n_steps, long sub, double *figs, double *snaps, long v0,
                     long v1);
void st_jacobians(const double *X, long n_rows, long n_states, const double *times, const double *irefs,
                  const double *P, long n_par, const double *T3, long t_rows, long t_n, const int64_t *tix,
                  const int64_t *vix, double *out, double *scratch);

#endif
