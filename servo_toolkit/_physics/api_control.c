/* Exported command.h, feedforward.h and control.h functions (see api_control.h). */
#include "api_control.h"
#include "command.h"
#include "control.h"
#include "feedforward.h"

double st_controller_sample(double t, double *x, const double *P, Tab T, double *work)
{
    return controller_sample(t, x, P, T, work);
}

double st_controller_update(double r, double *x, const double *P, Tab T, double *work, double i_ff, double w_ff)
{
    return controller_update(r, x, P, T, work, i_ff, w_ff);
}

void st_continuous_command(double t, const double *P, Tab T, double *r, double *i_ff, double *w_ff)
{
    continuous_command(t, P, T, r, i_ff, w_ff);
}

double st_reference(double t, const double *P) { return reference(t, P); }
double st_command(double t, const double *P) { return command(t, P); }

void st_feedforward(double t, const double *P, Tab T, double *r, double *i_ff, double *w_ff)
{
    feedforward(t, P, T, r, i_ff, w_ff);
}

double st_motor_angle(const double *P, Tab T, double p) { return motor_angle(P, T, p); }
double st_measured_angle(double q, const double *P) { return measured_angle(q, P); }
double st_measured_motor_angle(const double *P, Tab T, double p) { return measured_motor_angle(P, T, p); }

double st_motion(const double *x, const double *P, double r, double th, double wm, double *dx, long base,
                 int write_state)
{
    return motion(x, P, r, th, wm, dx, base, write_state);
}

void st_schedule_factors(const double *P, double q, double *g_e, double *g_w) { schedule_factors(P, q, g_e, g_w); }

void st_table_rates(double t, const double *P, double *r, double *rd, double *rdd) { table_rates(t, P, r, rd, rdd); }

void st_move_rates(double t, const double *P, double *r, double *rd, double *rdd) { move_rates(t, P, r, rd, rdd); }
