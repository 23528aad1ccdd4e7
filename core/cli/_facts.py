"""The flags of ``handeye solve`` and ``handeye calibrate`` that state facts about the cell, which
go to the problem's validation as well as to the solve (they are not solver options):

- ``--tz-X``, ``--tz-Y``: a robot whose rotations all share one axis (a SCARA) cannot determine
  the translation of X along that axis; the user gives it (handeye.problems.planar, docs/planar.md);
- ``--camera-scale unknown``: the camera's translations are known only up to scale (monocular
  SLAM or structure from motion; handeye.estimation.camera_scale, docs/camera-scale.md); in a cell of several
  cameras ``--camera-scale cam0,wrist1`` names the monocular cameras, each with its own scale
  (`camera_scale_value`).
"""

from __future__ import annotations

import argparse
from typing import Any

from handeye.base.errors import InputError
from handeye.cli._common import finite_number
from handeye.workflow.solving import in_robot_unit  # noqa: F401 (the residuals' data, as before)

#: flag -> the keyword of handeye.solve
FACTS = {"--tz-X": "tz_X", "--tz-Y": "tz_Y", "--camera-scale": "camera_scale"}


def add_flags(parser: argparse.ArgumentParser, unit: str) -> None:
    """Add --tz-X, --tz-Y (`unit`: the length unit their values are in) and --camera-scale."""
    parser.add_argument("--tz-X", dest="tz_X", type=finite_number, metavar="VALUE",
                        help="planar robot (a SCARA: every rotation about one axis): the translation of X along that "
                             f"axis, which such data cannot determine, in {unit} (from CAD or a measurement; 0 solves "
                             "the other parameters); for a SCARA flange simply X's z; docs/planar.md")
    parser.add_argument("--tz-Y", dest="tz_Y", type=finite_number, metavar="VALUE",
                        help="axyb, planar robot: Y's translation along the robot's rotation axis instead of --tz-X "
                             "(either fixes both)")
    parser.add_argument("--camera-scale", dest="camera_scale", type=camera_scale_value,
                        metavar="known|unknown|CAMERA,...",
                        help="'unknown': the camera's translations are known only up to scale (monocular SLAM, "
                             "structure from motion); the scale is estimated with X (and Y) by auto, refine and "
                             "so3-sdp; default known (the camera's translations in the robot's unit); several "
                             "cameras (axyb-multi): the monocular cameras' names, comma separated (cam0,wrist1), "
                             "each with its own scale; docs/camera-scale.md")


def camera_scale_value(text: str) -> str | list[str]:
    """``--camera-scale``'s value: ``known``, ``unknown``, or camera names separated by commas
    (a list)."""
    text = text.strip()
    if text in ("known", "unknown"):
        return text
    names = [name.strip() for name in text.split(",")]
    if not all(names):
        raise argparse.ArgumentTypeError(f"expected known, unknown or camera names separated by commas (cam0,wrist1), "
                                         f"got {text!r}")
    return names


def take(args: argparse.Namespace, options: dict[str, Any]) -> dict[str, Any]:
    """The facts given by the flags, or as ``--option tz_X=VALUE`` (removed from `options`)."""
    facts = {key: getattr(args, key) for key in FACTS.values() if getattr(args, key, None) is not None}
    for key in FACTS.values():
        if key in options:
            if key in facts:
                raise InputError(f"{key} is given twice (--{key.replace('_', '-')} and --option {key}=...); give it once")
            facts[key] = options.pop(key)
    return facts
