"""`SolverSpec`: what a solver plugin declares when it registers.

A spec is pure data plus one callable, ``run(data, options, backend) -> SolverOutput``. The host
(`handeye.host.api`) does everything shared: name look-up, backend choice and availability, option
parsing, timing, checking that the unknowns returned are in SE(3), and building the `Solution`.
"""

from __future__ import annotations

import dataclasses
import importlib.util
from collections.abc import Callable, Mapping
from typing import Any

from handeye.framework.options import NoOptions, parse_options
from handeye.framework.solution import SolverOutput

#: run(validated problem data, options dataclass instance, backend name) -> SolverOutput
RunFunction = Callable[[Any, Any, str], SolverOutput]


@dataclasses.dataclass(frozen=True)
class SolverSpec:
    """Declaration of one solver.

    name: kebab-case; unique per problem (one name may serve several problems, see `Registry`).
    problems: names of the problems it solves.
    run: the solver itself.
    backends: backend name -> the importable modules it needs (checked with
        `importlib.util.find_spec`, without importing them). A solver with no optional
        dependency has one backend, conventionally ``"numpy"``.
    default_backend: used when the caller gives none; must be a key of ``backends``.
    options: frozen dataclass of the options; unknown keys are rejected.
    citation: the method's reference.
    summary: one line shown by ``handeye list``.
    unit_invariant: True when scaling every translation by s scales the translations of the
        answer by s and leaves rotations unchanged; or, when that depends on the options (e.g. a
        ``normalize`` option), a callable ``(options instance) -> bool``. Read it through
        `is_unit_invariant`. The shared suite checks both ways: invariance where declared, a
        change of the answer where not.
    exact: True when noise-free data are recovered to machine precision; False for numerical
        solvers whose accuracy is bounded by their tolerance (the tests read this).
    check: optional ``check(backend) -> reason or None``, called lazily for availability
        conditions that a module look-up cannot see (e.g. a function missing from a version).
    simulate_options: options of the problem's simulator that make data this solver can solve,
        e.g. ``{"protocol": "phases"}`` for a method that needs one robot to hold still while the
        other moves; the shared tests simulate its cases with them.
    planar_mode: True when the solver honours the planar (4-DOF) mode: data whose robot rotates
        about one axis, with the translation that leaves undetermined given by the user (the
        validated data's ``planar``); the host refuses such data for the other solvers.
    camera_scale_mode: True when the solver honours data whose camera translations are known
        only up to scale (``camera_scale="unknown"``, `handeye.estimation.camera_scale`); the host refuses
        such data for the other solvers.
    fits_images: True when the solver fits the board images themselves (the corners' pixels,
        the data's ``images``) rather than the poses PnP gives: where a cell's stations come from
        images, ``handeye calibrate`` prefers it (`handeye.workflow.solving.image_solver`), and the
        default studies on pose data leave it out. Its `simulate_options` make data with images.
    variants: (option, values) when one option selects between different methods (OpenCV's
        five hand-eye methods behind ``method``): default studies compare one entry per value,
        labelled ``name (value)``; None: the solver enters once.
    """

    name: str
    problems: tuple[str, ...]
    run: RunFunction
    backends: Mapping[str, tuple[str, ...]] = dataclasses.field(default_factory=lambda: {"numpy": ()})
    default_backend: str = "numpy"
    options: type = NoOptions
    citation: str = ""
    summary: str = ""
    unit_invariant: bool | Callable[[Any], bool] = False
    exact: bool = True
    check: Callable[[str], str | None] | None = None
    planar_mode: bool = False
    camera_scale_mode: bool = False
    simulate_options: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    fits_images: bool = False
    variants: tuple[str, tuple[Any, ...]] | None = None

    def __post_init__(self) -> None:
        if self.default_backend not in self.backends:
            raise ValueError(
                f"solver {self.name!r}: default_backend {self.default_backend!r} is not one of "
                f"its backends {sorted(self.backends)}"
            )
        if not dataclasses.is_dataclass(self.options):
            raise ValueError(f"solver {self.name!r}: options must be a dataclass type")
        if not (isinstance(self.unit_invariant, bool) or callable(self.unit_invariant)):
            raise ValueError(f"solver {self.name!r}: unit_invariant must be a bool or a callable "
                             f"(options) -> bool, got {self.unit_invariant!r}")

    def is_unit_invariant(self, options: Any = None) -> bool:
        """Whether the answer is unit invariant (see `unit_invariant`) with these options.

        options: an instance of the `options` dataclass, a mapping of option keywords (as given
        to `handeye.solve`; validated the same way), or None for the defaults.
        """
        if not callable(self.unit_invariant):
            return self.unit_invariant
        if options is None:
            options = self.options()
        elif isinstance(options, Mapping):
            options = parse_options(self.options, options, self.name)
        return bool(self.unit_invariant(options))

    def unavailable_reason(self, backend: str) -> str | None:
        """Why `backend` cannot run here (missing module, ...), or None when it can."""
        for module in self.backends[backend]:
            if not _installed(module):
                return f"backend {backend!r} of solver {self.name!r} needs the Python module {module!r}; install it (pip install {_PIP_NAMES.get(module, module)})"
        if self.check is not None:
            return self.check(backend)
        return None

    def cannot_solve(self, data: Any) -> str | None:
        """Why this solver cannot solve validated `data` (a mode of the data it does not honour),
        worded to follow the solver's name; None when it can. The one capability check: the host
        refuses such data with it, and refine a start solver that cannot solve them."""
        if getattr(data, "planar", None) is not None and not self.planar_mode:
            return "has no planar (4-DOF) mode for data whose robot rotates about one axis"
        if getattr(data, "camera_scale_unknown", False) and not self.camera_scale_mode:
            return "takes the camera's translations as metric, and these data have camera_scale='unknown'"
        return None

    def option_names(self) -> list[str]:
        return [f.name for f in dataclasses.fields(self.options)]


#: modules found installed -> the finder (importlib.util.find_spec) that found them. A module found
#: stays installed for the process, so it is looked up once (find_spec costs ~25 us, and a solve
#: asks several times); a replaced finder (a test simulating a missing package) is asked again.
_INSTALLED: dict[str, Any] = {}


def _installed(module: str) -> bool:
    """Whether Python module `module` can be imported here (`_INSTALLED`)."""
    finder = importlib.util.find_spec
    if _INSTALLED.get(module) is finder:
        return True
    if finder(module) is None:
        return False
    _INSTALLED[module] = finder
    return True


_PIP_NAMES = {"cv2": "opencv-python-headless", "casadi": "casadi", "picos": "picos", "cvxpy": "cvxpy"}
