/* The tables' type alone, for the api headers the extension module includes (they must not
   bring the layout's macros into the module's C file). */
#ifndef SERVO_TAB_H
#define SERVO_TAB_H

typedef struct {
    const double *v;
    long n;
} Tab;

#endif
