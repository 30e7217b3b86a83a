/* Exported rhs.h, friction.h and compliance.h functions (see api_rhs.h). */
#include "api_rhs.h"
#include "rhs.h"

long st_rhs_nx_phys(void) { return NX_PHYS; }
long st_rhs_naux(void) { return NAUX; }

void st_rhs(double t, double *x, long nx, const double *P, Tab T, double iref_held, double *dx, double *aux)
{
    rhs(t, x, nx, P, T, iref_held, dx, aux);
}

void st_rhs_phys(double t, double p, double pd, double q, double qd, double cur, double xi, double s,
                 const double *P, Tab T, double iref_held, double *x, double *dx, double *out)
{
    rhs_phys(t, p, pd, q, qd, cur, xi, s, P, T, iref_held, x, dx, out);
}

double st_contact(double tau_c, double tau_d) { return contact(tau_c, tau_d); }

double st_speed_sign(double n, double tw) { return speed_sign(n, tw); }

double st_slip_friction(double v, double tc, double ts, double inv_vs, double direction)
{
    return slip_friction(v, tc, ts, inv_vs, direction);
}

double st_stuck_or_breaking(double applied, double cap) { return stuck_or_breaking(applied, cap); }

double st_gear_at_rest(double torque, double moment, double cap_t, double cap_m, double fwd_loss, double back_loss,
                       double gauge)
{
    return gear_at_rest(torque, moment, cap_t, cap_m, fwd_loss, back_loss, gauge);
}
