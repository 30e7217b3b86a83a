/* Entry points of rhs.h, friction.h and compliance.h for the extension module (tests and the
   callers that evaluate the right-hand side once). */
#ifndef SERVO_API_RHS_H
#define SERVO_API_RHS_H

#include "tab.h"

/* the sizes the wrappers check: the physical states, the aux entries */
long st_rhs_nx_phys(void);
long st_rhs_naux(void);

void st_rhs(double t, double *x, long nx, const double *P, Tab T, double iref_held, double *dx, double *aux);
void st_rhs_phys(double t, double p, double pd, double q, double qd, double cur, double xi, double s,
                 const double *P, Tab T, double iref_held, double *x, double *dx, double *out);
double st_contact(double tau_c, double tau_d);
double st_speed_sign(double n, double tw);
double st_slip_friction(double v, double tc, double ts, double inv_vs, double direction);
double st_stuck_or_breaking(double applied, double cap);
double st_gear_at_rest(double torque, double moment, double cap_t, double cap_m, double fwd_loss, double back_loss,
                       double gauge);

#endif
