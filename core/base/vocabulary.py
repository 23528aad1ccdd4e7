"""The words handeye's data, files, options and messages share, each defined once: the setups,
how stations pair into motions, the length and angle units and their factors. Every reader,
command and problem takes its choices from here, so that a file, a flag and a message never
disagree on a spelling (docs/conventions.md)."""

from __future__ import annotations

import math

#: the camera on the robot's flange (X = T_flange_cam) or fixed in the cell (X = T_base_cam for
#: A X = X B; Y = T_base_cam for A X = Y B): docs/conventions.md
EYE_IN_HAND = "eye-in-hand"
EYE_TO_HAND = "eye-to-hand"
SETUPS = (EYE_IN_HAND, EYE_TO_HAND)

#: how stations pair into motions for A X = X B: neighbours in the data's order, or every two
PAIRINGS = ("consecutive", "all")

#: metres per length unit, every unit a data file may state
METRES_PER = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
#: the length units of pose files, cells, boards and arms
LENGTH_UNITS = ("mm", "m")
#: radians per angle unit (joint readings, DH tables, Euler angles)
RADIANS_PER = {"deg": math.pi / 180.0, "rad": 1.0}
ANGLE_UNITS = tuple(RADIANS_PER)


def millimetres_per(unit: str) -> float:
    """The factor from `unit` (a key of METRES_PER) to millimetres: 1000.0, 10.0 or 1.0 exactly."""
    return METRES_PER[unit] * 1000.0
