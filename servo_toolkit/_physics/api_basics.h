/* Entry points of vmath.h and tables.h for the extension module (tests and callers). */
#ifndef SERVO_API_BASICS_H
#define SERVO_API_BASICS_H

#include "tab.h"

/* vmath.h's tanh cut-offs: |a| from which tanh(a) is +-1, below which the rational form */
extern const double st_tanh_one;
extern const double st_tanh_small;

double st_tanh(double a);
double st_exp_pos(double y);
double st_exp_neg(double y);
void st_hermite(Tab T, long row, const double *P, double q, double *val, double *der);

#endif
