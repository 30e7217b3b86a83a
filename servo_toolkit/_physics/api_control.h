/* Entry points of command.h, feedforward.h and control.h for the extension module (tests and
   callers that need one value). */
#ifndef SERVO_API_CONTROL_H
#define SERVO_API_CONTROL_H

#include "tab.h"

double st_controller_sample(double t, double *x, const double *P, Tab T, double *work);
double st_controller_update(double r, double *x, const double *P, Tab T, double *work, double i_ff, double w_ff);
void st_continuous_command(double t, const double *P, Tab T, double *r, double *i_ff, double *w_ff);
double st_reference(double t, const double *P);
double st_command(double t, const double *P);
void st_feedforward(double t, const double *P, Tab T, double *r, double *i_ff, double *w_ff);
double st_motor_angle(const double *P, Tab T, double p);
double st_measured_angle(double q, const double *P);
double st_measured_motor_angle(const double *P, Tab T, double p);
double st_motion(const double *x, const double *P, double r, double th, double wm, double *dx, long base,
                 int write_state);
void st_schedule_factors(const double *P, double q, double *g_e, double *g_w);
void st_table_rates(double t, const double *P, double *r, double *rd, double *rdd);
void st_move_rates(double t, const double *P, double *r, double *rd, double *rdd);

#endif
