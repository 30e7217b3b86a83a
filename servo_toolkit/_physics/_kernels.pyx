# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""The compiled physics: the right-hand side, the integrators, the batch and the cam kernels.

C99 sources beside this file, one header per concern; this module only converts arrays and
releases the GIL around whole runs. Built by ``pip install .`` (or ``pip install -e .``,
which rebuilds it in place).
"""

include "decl_common.pxi"
include "wrap_basics.pxi"
include "wrap_control.pxi"
include "wrap_rhs.pxi"
include "wrap_cam.pxi"
include "wrap_integrate.pxi"
include "wrap_batch.pxi"
