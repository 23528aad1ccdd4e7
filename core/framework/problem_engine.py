"""The engine's and the self-check's parts of the problem contract: the least-squares model
``refine`` and ``auto`` fit and the starts they take (`EnginePart`), and what the host's
self-check needs (`SelfCheckPart`: its model, the noise it expects, the robot's pose at each row,
the robot's main axes). Optional: a problem without them is solved by its own solvers and
checked by the shared output rules only. Also the problem's unknowns as single poses in the
engine's order (`flat_names`, `flatten`, `unflatten`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

#: the unknowns by name ({"X": 4x4, "Y": 4x4, or a (k, 4, 4) stack}), as every part of the contract takes them
NamedPoses = Mapping[str, np.ndarray]


class EnginePart:
    """What ``refine`` and ``auto`` ask of a problem (`handeye.estimation.nlls`)."""

    #: registered solvers that give ``refine`` and ``auto`` their start, in order of preference;
    #: those in `certifiable_starts` prove their answer globally optimal (auto then needs no
    #: second start); errors of `start_refusals` pass on to the next start besides a solver's
    #: failure (e.g. InputError of a start that serves one data protocol only)
    starts: ClassVar[tuple[str, ...]] = ()
    certifiable_starts: ClassVar[tuple[str, ...]] = ()
    start_refusals: ClassVar[tuple[type[Exception], ...]] = ()

    def pose_model(self, data: Any) -> Any:
        """The shared least-squares engine's model of validated `data` (a
        `handeye.estimation.nlls.PoseModel`, its unknowns in the order `flat_unknowns` gives),
        or None: then ``refine`` and ``auto`` do not serve the problem. Default: the data's own
        ``pose_model`` attribute, when they have one."""
        return getattr(data, "pose_model", None)

    @property
    def refinable(self) -> bool:
        """Whether the problem offers the engine a model (`pose_model` overridden, or its data
        type carrying one): ``refine`` and ``auto`` register for it."""
        return type(self).pose_model is not EnginePart.pose_model or hasattr(getattr(self, "data_type", None),
                                                                             "pose_model")


class SelfCheckPart:
    """What the host's self-check asks of a problem (`handeye.checks.self_check`)."""

    def check_model(self, data: Any, unknowns: NamedPoses) -> tuple[Any, tuple[np.ndarray, ...], tuple[str, ...]] | None:
        """For the host's self-check (`handeye.checks.self_check`): a least-squares model of the data
        (`handeye.estimation.nlls.PoseModel`), the poses to start it from (the answer's, with any nuisance
        unknown of the model fitted to it) and the names among the model's unknowns that are
        the answer's; None: the problem offers no such check."""
        return None

    def expected_rotation_residual(self, data: Any) -> float | None:
        """The median rotation residual (rad, of `residuals`) a correct answer leaves at the
        noise these data show, measured without the unknowns (e.g. from the rotation angles of
        paired motions, which must agree); None when the data cannot tell."""
        return None

    def rotation_axes(self, data: Any) -> dict[str, np.ndarray]:
        """Per unknown, the robot's main rotation axis (unit) in the frame the unknown is
        expressed in, for naming a poorly determined direction; empty when not known."""
        return {}

    def configurations(self, data: Any) -> np.ndarray | None:
        """The robot's pose (T_base_flange, or its inverse) at each row of the model
        `check_model` gives, (m, 4, 4), for the self-check's test of residuals that follow the
        arm's configuration (systematic robot errors, `handeye.checks.systematic`); None (the
        default): the problem's rows are not stations of one robot, the test is skipped."""
        return None


def flat_names(problem: Any, data: Any) -> tuple[str, ...]:
    """The problem's unknowns as single poses, in order: a stack `X` of k poses (`stack_sizes`)
    as ``X[0]``, ..., ``X[k-1]`` (the order of `Problem.pose_model`'s unknowns)."""
    sizes = problem.stack_sizes(data)
    return tuple(item for name in problem.unknowns
                 for item in ([f"{name}[{k}]" for k in range(sizes[name])] if name in sizes else [name]))


def flatten(problem: Any, data: Any, unknowns: Mapping[str, np.ndarray]) -> tuple[np.ndarray, ...]:
    """The unknowns as a tuple of single poses (`flat_names`' order)."""
    sizes = problem.stack_sizes(data)
    out: list[np.ndarray] = []
    for name in problem.unknowns:
        T = np.asarray(unknowns[name], dtype=float)
        out += list(T) if name in sizes else [T]
    return tuple(out)


def unflatten(problem: Any, data: Any, poses: tuple[np.ndarray, ...] | list[np.ndarray]) -> dict[str, np.ndarray]:
    """The inverse of `flatten`: {unknown: 4x4, or a (k, 4, 4) stack}."""
    sizes, out, k = problem.stack_sizes(data), {}, 0
    for name in problem.unknowns:
        n = sizes.get(name)
        out[name] = np.stack(poses[k:k + n]) if n is not None else np.asarray(poses[k])
        k += 1 if n is None else n
    if k != len(poses):
        raise ValueError(f"{len(poses)} poses for unknowns {flat_names(problem, data)}")
    return out
