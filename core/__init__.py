"""handeye: hand-eye and robot-world calibration with pluggable problems and solvers.

Public API::

    import handeye
    sol = handeye.solve("axyb", A=A, B=B, solver="lmi-sdp", backend="picos")
    sol.X, sol.Y, sol.status, sol.diagnostics
    from handeye.problems.axxb import motions
    sol = handeye.solve("axxb", **motions(robot_poses, camera_poses, setup="eye-in-hand"))
    sol.X  # T_flange_cam
    result = handeye.calibrate(handeye.Cell.from_file("cell.yaml"))   # a cell's recordings, checked
    result.X, result.status, result.ros2_static_transform(), result.write_report("report.html")

See docs/conventions.md for what A, B, X, Y are in eye-in-hand and eye-to-hand setups, for both
problems.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from importlib.metadata import PackageNotFoundError, version
from types import ModuleType
from typing import Any

from handeye.base.errors import (
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
from handeye.base.moved import REMOVAL_DATE
from handeye.estimation.pose_model import PoseModel
from handeye.framework.hookspecs import hookimpl
from handeye.framework.options import NoOptions
from handeye.framework.problem import Problem, pose_discrepancy
from handeye.framework.problem_cell import Frame, StationReader
from handeye.framework.solution import Solution, SolverOutput, Status
from handeye.framework.solver import SolverSpec
from handeye.host.api import run_registered, solve
from handeye.host.registry import get_registry, list_problems, list_solvers

#: submodules that ``handeye.<name>`` imports on first use (PEP 562), so that ``import handeye``
#: stays cheap: ``handeye.io.load_file(...)`` works without ``import handeye.io`` first.
_LAZY_SUBMODULES = ("examples", "harness", "io", "problems")
#: public names defined in a submodule that ``import handeye`` does not import (it reads files,
#: OpenCV, the checks): name -> its module, imported on first use
_LAZY_NAMES = {"calibrate": "workflow.calibration", "Cell": "workflow.cell", "CalibrationResult": "workflow.result"}
#: modules that moved -> where they live now: those of the flat layout before the layers
#: (``handeye.se3``, ``handeye.options``, ...) and those the layer order moved down or up
#: (``handeye.framework.errors`` -> ``handeye.base.errors``, ...). Their old paths keep working and
#: give the same module object (`_MovedModules`), with a DeprecationWarning naming the new path:
#: they are removed on REMOVAL_DATE (docs/changelog.md).
_MOVED = {
    "api": "host.api", "errors": "base.errors", "registry": "host.registry",
    **{m: f"framework.{m}" for m in ("hookspecs", "isolation", "options", "problem", "processes", "solution",
                                     "solver")},
    **{m: f"geometry.{m}" for m in ("se3", "so3_fast", "dualquat", "kinematics", "linalg")},
    **{m: f"estimation.{m}" for m in ("nlls", "whitening", "robust", "noise", "noise_sources", "kronecker",
                                      "so3_relaxation", "rotation_cost", "trust_region", "camera_scale",
                                      "camera_scales")},
    "validation": "geometry.validation", "self_check": "checks.self_check", "plausibility": "workflow.plausibility",
    # the layer order of pyproject.toml: errors at the bottom, the host above the checks
    "framework.errors": "base.errors", "framework.api": "host.api", "framework.registry": "host.registry",
    "checks.validation": "geometry.validation", "checks.plausibility": "workflow.plausibility",
    "streams.resample": "geometry.resample", "planning.watch_source": "workflow.watch_source",
    "cli._kinhec_report": "harness.kinhec_report", "cli._kinhec_fixtures": "harness.kinhec_fixtures",
    **{m: f"io.{m}" for m in ("npz", "pose_formats", "pose_readers", "bag_readers", "input_files", "output_files",
                              "examples")},
    "station_matching": "streams.station_matching",
    **{m: f"workflow.{m}" for m in ("quality_report", "report_layout", "report_render", "report_images",
                                    "report_plots")},
    # the problems' modules before one package per problem
    "problems.axyb_geometry": "problems.axyb.geometry", "problems.axyb_images": "problems.axyb.images",
    "problems.axxb_geometry": "problems.axxb.geometry", "problems.axbycz_geometry": "problems.axbycz.geometry",
    "problems.axbycz_kronecker": "problems.axbycz.kronecker",
    # lmi-sdp's modules before its package
    "plugins.lmi_sdp_axxb": "plugins.lmi_sdp.axxb", "plugins.lmi_sdp_axbycz": "plugins.lmi_sdp.axbycz",
    "plugins.lmi_sdp_casadi": "plugins.lmi_sdp.casadi", "plugins.lmi_sdp_clarabel": "plugins.lmi_sdp.clarabel",
}


class _MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports ``handeye.<old name>`` of `_MOVED` as the module at its new place (the same object,
    under both names in sys.modules), on first use only."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> importlib.machinery.ModuleSpec | None:
        head, _, tail = fullname.partition(".")
        if head != __name__ or tail not in _MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        old = spec.name.partition(".")[2]
        new = f"{__name__}.{_MOVED[old]}"
        if old in _LAZY_SUBMODULES:  # a public name of the package (handeye.examples), not an old path
            return importlib.import_module(new)
        warnings.warn(f"{spec.name} is now {new}: import it from there ({spec.name} goes on {REMOVAL_DATE})",
                      DeprecationWarning, stacklevel=2)
        return importlib.import_module(new)

    def exec_module(self, module: ModuleType) -> None:
        """Nothing: the module was executed at its new place."""


if not any(isinstance(f, _MovedModules) for f in sys.meta_path):
    sys.meta_path.insert(0, _MovedModules())

try:
    __version__ = version("handeye")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"

__all__ = [
    "BackendUnavailableError",
    "CalibrationResult",
    "Cell",
    "DegenerateDataError",
    "Frame",
    "HandEyeError",
    "InputError",
    "NoOptions",
    "PluginLoadWarning",
    "PluginRegistrationError",
    "PoseModel",
    "Problem",
    "Solution",
    "SolverError",
    "SolverOutput",
    "SolverSpec",
    "SolverTimeoutError",
    "StationReader",
    "Status",
    "UnknownPluginError",
    "calibrate",
    "examples",
    "get_registry",
    "harness",
    "hookimpl",
    "io",
    "list_problems",
    "list_solvers",
    "pose_discrepancy",
    "problems",
    "run_registered",
    "solve",
]


def __getattr__(name: str) -> Any:
    """``handeye.io``, ``handeye.examples``, ``handeye.harness``, ``handeye.problems`` and
    ``handeye.calibrate``, ``handeye.Cell``, ``handeye.CalibrationResult``: imported on first
    access (PEP 562); any other unknown name is an AttributeError as usual."""
    if name in _LAZY_NAMES:
        value = getattr(importlib.import_module(f"{__name__}.{_LAZY_NAMES[name]}"), name)
        globals()[name] = value
        return value
    if name in _LAZY_SUBMODULES or name in _MOVED:
        return importlib.import_module(f"{__name__}.{name}")  # the import binds it on the package
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
