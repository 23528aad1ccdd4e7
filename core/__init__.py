"""handeye: hand-eye and robot-world calibration with pluggable problems and solvers.

Public API::

    import handeye
    sol = handeye.solve("axyb", A=A, B=B, solver="lmi-sdp", backend="picos")
    sol.X, sol.Y, sol.status, sol.diagnostics
    from handeye.problems.axxb import motions
    sol = handeye.solve("axxb", **motions(robot_poses, camera_poses, setup="eye-in-hand"))
    sol.X  # T_flange_cam

See docs/conventions.md for what A, B, X, Y are in eye-in-hand and eye-to-hand setups, for both
problems.
"""

from __future__ import annotations

import importlib
from importlib.metadata import PackageNotFoundError, version
from types import ModuleType

from .api import run_registered, solve
from .errors import (
    BackendUnavailableError,
    DegenerateDataError,
    HandEyeError,
    InputError,
    PluginLoadWarning,
    PluginRegistrationError,
    SolverError,
    SolverTimeoutError,
    UnknownPluginError,
)
from .hookspecs import hookimpl
from .options import NoOptions
from .problem import Problem
from .registry import get_registry, list_problems, list_solvers
from .solution import Solution, SolverOutput, Status
from .solver import SolverSpec

#: submodules that ``handeye.<name>`` imports on first use (PEP 562), so that ``import handeye``
#: stays cheap: ``handeye.io.load_file(...)`` works without ``import handeye.io`` first.
_LAZY_SUBMODULES = ("examples", "harness", "io", "problems")

try:
    __version__ = version("handeye")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"

__all__ = [
    "BackendUnavailableError",
    "DegenerateDataError",
    "HandEyeError",
    "InputError",
    "NoOptions",
    "PluginLoadWarning",
    "PluginRegistrationError",
    "Problem",
    "Solution",
    "SolverError",
    "SolverOutput",
    "SolverSpec",
    "SolverTimeoutError",
    "Status",
    "UnknownPluginError",
    "examples",
    "get_registry",
    "harness",
    "hookimpl",
    "io",
    "list_problems",
    "list_solvers",
    "problems",
    "run_registered",
    "solve",
]


def __getattr__(name: str) -> ModuleType:
    """``handeye.io``, ``handeye.examples``, ``handeye.harness``, ``handeye.problems``: imported
    on first access (PEP 562); any other unknown name is an AttributeError as usual."""
    if name in _LAZY_SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")  # the import binds it on the package
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
