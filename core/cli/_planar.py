"""The planar-mode flags of ``handeye solve`` and ``handeye calibrate``: ``--tz-X``, ``--tz-Y``.

A robot whose rotations all share one axis (a SCARA) cannot determine the translation of X along
that axis; the user gives it (handeye.problems.planar, docs/planar.md). It is a fact about the
cell, not a solver option, so it goes to the problem's validation as well as to the solve.
"""

from __future__ import annotations

import argparse
from typing import Any

from ..errors import InputError

#: flag -> the keyword of handeye.solve
FACTS = {"--tz-X": "tz_X", "--tz-Y": "tz_Y"}


def add_flags(parser: argparse.ArgumentParser, unit: str) -> None:
    """Add --tz-X and --tz-Y; `unit` says which length unit the value is in."""
    parser.add_argument("--tz-X", dest="tz_X", type=float, metavar="VALUE",
                        help="planar robot (a SCARA: every rotation about one axis): the translation of X along that "
                             f"axis, which such data cannot determine, in {unit} (from CAD or a measurement; 0 solves "
                             "the other parameters); for a SCARA flange simply X's z; docs/planar.md")
    parser.add_argument("--tz-Y", dest="tz_Y", type=float, metavar="VALUE",
                        help="axyb, planar robot: Y's translation along the robot's rotation axis instead of --tz-X "
                             "(either fixes both)")


def take(args: argparse.Namespace, options: dict[str, Any]) -> dict[str, float]:
    """The facts given by the flags, or as ``--option tz_X=VALUE`` (removed from `options`)."""
    facts = {key: getattr(args, key) for key in FACTS.values() if getattr(args, key, None) is not None}
    for key in FACTS.values():
        if key in options:
            if key in facts:
                raise InputError(f"{key} is given twice (--{key.replace('_', '-')} and --option {key}=...); give it once")
            facts[key] = options.pop(key)
    return facts
