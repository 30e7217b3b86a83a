"""The one array type the compiled kernels take their stroke tables as (:func:`frozen_tables`).

Inside the kernels a table row is interpolated by cubic Hermite, values and exact derivatives
(``servo_toolkit/_physics/tables.h``; :func:`servo_toolkit.sim.kernel.hermite` from Python).
Layout of the rows in :mod:`servo_toolkit.sim.layout`."""

from __future__ import annotations

import numpy as np


def frozen_tables(T) -> np.ndarray:
    """``T`` as a read-only C-contiguous float64 array (a copy only when it is not one), as
    every kernel reads it: a run never writes its tables."""
    if T.flags.writeable or not T.flags.c_contiguous or T.dtype != np.float64:
        T = np.array(T, dtype=np.float64, order="C")
        T.setflags(write=False)
    return T
