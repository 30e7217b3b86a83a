"""Angle conversions, one name per direction: a figure in rad times :data:`DEG_PER_RAD` is in
deg, a figure in deg times :data:`RAD_PER_DEG` is in rad."""

from __future__ import annotations

import math

#: deg per rad (180 / pi): rad -> deg
DEG_PER_RAD = 180.0 / math.pi
#: rad per deg (pi / 180): deg -> rad
RAD_PER_DEG = math.pi / 180.0

__all__ = ["DEG_PER_RAD", "RAD_PER_DEG"]
