"""Frequency response of the nonlinear loop by a periodic multisine, estimated as a rig's log
is (``servo-toolkit sweep --method multisine``): the command, the run and the estimate in
:mod:`.run` (``multisine_sweep``), the response and its views in :mod:`.result`
(``MultisineResult``)."""

from .result import MultisineResult
from .run import (DEFAULT_PERIODS, RESPONSES, MultisinePlan, MultisineSpec, linear_plant_response, multisine_spec,
                  multisine_sweep, schroeder)

__all__ = ["DEFAULT_PERIODS", "RESPONSES", "MultisinePlan", "MultisineResult", "MultisineSpec", "linear_plant_response",
           "multisine_spec", "multisine_sweep", "schroeder"]
