/* Exported vmath.h and tables.h functions (see api_basics.h). */
#include "api_basics.h"
#include "tables.h"
#include "vmath.h"

const double st_tanh_one = TANH_ONE;
const double st_tanh_small = TANH_SMALL;

double st_tanh(double a) { return vtanh(a); }
double st_exp_pos(double y) { return exp_pos(y); }
double st_exp_neg(double y) { return exp_neg(y); }

void st_hermite(Tab T, long row, const double *P, double q, double *val, double *der)
{
    hermite(T, row, P, q, val, der);
}
