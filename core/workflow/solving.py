"""Which solver a calibration runs and how long it may take, when the user chose neither: the
defaults shared by ``handeye.calibrate``, ``handeye calibrate`` and ``handeye solve``.

- `default_solver`: the host's default (``auto``, `handeye.host.api.DEFAULT_SOLVER`) when
  registered for the problem, else the first of the problem's starts that is;
- board images (axyb): the solver that fits them (`SolverSpec.fits_images`, `image_solver`), which gives way to
  the pose-based default where that predicts the corners of held-out stations better
  (`pose_based_instead`);
- `time_limit`: none for handeye's own solvers, `PLUGIN_TIME_LIMIT` for a third party's, so a
  hanging plugin cannot hang a calibration; 0 means no limit.

Also the statuses whose unknowns must not be used (`UNUSABLE`), the camera's translations
scaled into the robot's unit when the camera scale (or, in a cell of several cameras, each
monocular camera's scale) was estimated (`in_robot_unit`), and the validated data the residuals
are measured on (`measured_data`: the solve's own, `Solution.data`, unless scaled).

A pose-based answer from board images (`pose_based_intrinsics`) owes the uncertainty of
intrinsics calibrated from the same images as the corner fit does, found by re-solving with the
board poses PnP gives for intrinsics 1-sigma off (`handeye.vision.intrinsics_effect`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye.base.errors import HandEyeError, InputError
from handeye.framework.reported import Reported
from handeye.framework.solution import Solution, Status, jsonable
from handeye.host.api import DEFAULT_SOLVER
from handeye.host.registry import get_registry

#: folds of the stations over which the default corner fit is compared with the pose-based
#: answer by held-out corner prediction (`pose_based_instead`)
HELD_OUT_FOLDS = 3
#: statuses whose unknowns must not be used (the answer is shown for inspection only)
UNUSABLE = (Status.NOT_CONVERGED, Status.FAILED)
#: seconds a third-party plugin's solver may take by default
PLUGIN_TIME_LIMIT = 600.0


def default_solver(problem: str) -> str:
    """The host's default solver (`DEFAULT_SOLVER`) when registered for `problem`, else the first
    of the problem's starts (`Problem.starts`) that is; InputError when none is."""
    registry = get_registry()
    names = registry.solver_names(problem)
    for name in (DEFAULT_SOLVER, *registry.problem(problem).starts):
        if name in names:
            return name
    raise InputError(f"no default solver for problem {problem!r}; set `solver` to one of {names}")


def image_solver(problem: str) -> str | None:
    """The first solver registered for `problem` that fits the board images themselves
    (`SolverSpec.fits_images`), else None (the default solver then solves the board poses)."""
    registry = get_registry()
    return next((name for name in registry.solver_names(problem) if fits_images(problem, name)), None)


def fits_images(problem: str, solver: str) -> bool:
    """Whether `solver` of `problem` fits the board images themselves (`SolverSpec.fits_images`)."""
    registry = get_registry()
    return solver in registry.solver_names(problem) and registry.solver(solver, problem).fits_images


def pose_based_instead(solution: Solution, defaulted: bool) -> str | None:
    """Why the default reprojection answer gives way to the pose-based default solver, or None:
    when the pose-based answer predicts the corners of stations it was not fitted to better than
    the corner fit does (the solver's own held-out comparison, ``held_out``, asked for by
    `image_data`); only when no solver was chosen."""
    verdict = Reported.of(solution.diagnostics).held_out or {}
    if not defaulted or not fits_images(solution.problem, solution.solver) or not verdict.get("pose_based_better"):
        return None
    corners = verdict["reprojection_px"]
    fitted = "failed on some fold" if corners is None else f"{corners:.3g} px"
    return (f"over {verdict['folds']} folds of the stations, the pose-based answer predicts the board corners of "
            f"images it was not fitted to to {verdict['pose_based_px']:.3g} px RMS, the fit to the corners to "
            f"{fitted}: the answer is the pose-based one (`solver: {solution.solver}` forces the corner fit)")


def image_data(image_set: Any, solver: str, problem: str, compare: bool = False) -> dict[str, Any]:
    """The image observations as the solver's ``images`` field, for a solver that fits them only
    (of a problem whose data take them, ``images`` among its `Problem.optional_fields`); with
    `compare` (the solver was not chosen by the user) also its held-out comparison with the
    pose-based answer over HELD_OUT_FOLDS folds of the stations, where there are enough of them."""
    if (image_set is None or not fits_images(problem, solver)
            or "images" not in get_registry().problem(problem).optional_fields):
        return {}
    stations = len(image_set.observations.image_points)
    folds = {"held_out": HELD_OUT_FOLDS} if compare and stations >= 2 * HELD_OUT_FOLDS else {}
    return {"images": image_set.observations, **folds}


def time_limit(given: float | None, problem: str, solver: str) -> float | None:
    """The time limit of a solve, in seconds or None: `given` (0: none), else `PLUGIN_TIME_LIMIT`
    for a third party's solver and none for handeye's own. InputError for a negative or
    non-finite `given`."""
    if given is not None:
        from handeye.host.api import MAX_TIME_LIMIT

        if not 0 <= given <= MAX_TIME_LIMIT:
            raise InputError(f"`time_limit` must be a number of seconds from 0 (no limit) to {MAX_TIME_LIMIT:.2g} (a "
                             f"year), got {given:g}")
        return given or None
    registry = get_registry()
    if solver in registry.solver_names(problem) and not registry.is_builtin(solver, problem):
        return PLUGIN_TIME_LIMIT
    return None


def in_robot_unit(data: Mapping[str, Any], facts: Mapping[str, Any],
                  diagnostics: Mapping[str, Any]) -> Mapping[str, Any]:
    """The data with the camera's translations (B) in the robot's unit: multiplied by the camera
    scale the solve estimated when the scale is unknown (``camera_scale: unknown``), or, in a cell
    of several cameras (``camera_scale`` a list of camera names), each monocular camera's
    translations by its own scale (``diagnostics["camera_scales"]``: {name: s}, a name being one
    of the data's ``x_names`` or ``y_names``); else the data as they are (for the residuals shown
    to the user)."""
    given = facts.get("camera_scale")
    if given == "unknown":
        scale = Reported.of(diagnostics).camera_scale
        if scale is None:
            return data
        B = np.array(data["B"], dtype=float)
        B[:, :3, 3] *= scale
        return {**data, "B": B}
    scales = Reported.of(diagnostics).camera_scales if given is not None and not isinstance(given, str) else None
    if not scales:
        return data
    B = np.array(data["B"], dtype=float)
    for which in ("x", "y"):
        if data.get(f"{which}_index") is None:
            continue
        index = np.asarray(data[f"{which}_index"])
        given_names = data.get(f"{which}_names")
        names = ([f"{which.upper()}{k}" for k in range(int(index.max()) + 1)] if given_names is None
                 else [str(n) for n in given_names])
        for name, s in scales.items():
            if name in names:
                B[index == names.index(name), :3, 3] *= s
    return {**data, "B": B}


def measured_data(problem: Any, solution: Solution, data: Mapping[str, Any], facts: Mapping[str, Any]) -> Any:
    """The validated data the residuals shown to the user are measured on: the solve's own
    (`Solution.data`, validated once) when the camera's translations are metric as given, else
    `data` with them in the robot's unit (`in_robot_unit`), validated by `problem` with `facts`."""
    measured = in_robot_unit(data, facts, solution.diagnostics)
    if measured is data and solution.data is not None:
        return solution.data
    return problem.validate(**measured, **facts)


def pose_based_intrinsics(solution: Solution, image_set: Any, robot_poses: np.ndarray, cell: Any,
                          facts: Mapping[str, Any], options: Mapping[str, Any]) -> Solution:
    """`solution`, a pose-based answer from the board poses of `image_set` (a
    `handeye.vision.image_set.ImageSet`; the robot's poses `robot_poses` in its station order),
    with ``diagnostics["focal_per_permille"]``: how far each unknown's translation moves for a
    focal length 0.1% off; and, where the intrinsics carry a 1-sigma (``observations.
    intrinsics_std``: calibrated from these images, or given with one stated or assumed), its
    covariance and 1-sigma widened by theirs, with the warning where a translation's 1-sigma at
    least doubles (`handeye.vision.intrinsics_effect`). Found by re-solving `cell`'s problem with
    the same solver, facts and options (4 solves of a few ms). The corner fit
    (`SolverSpec.fits_images`), which does this itself, an unusable answer, or no images: `solution`
    as it is."""
    from handeye.host.api import solve
    from handeye.io.data_files import from_poses
    from handeye.vision import intrinsics_effect as effect

    if (image_set is None or fits_images(solution.problem, solution.solver) or solution.status in UNUSABLE
            or len(robot_poses) != len(image_set.T_cam_target)):
        return solution
    obs = image_set.observations
    names = list(effect.flat_poses(solution.unknowns))
    T0 = np.asarray(image_set.T_cam_target, dtype=float)
    slopes = [effect.pose_sensitivity(T, P, obs.camera) for T, P in zip(T0, obs.object_points)]

    def resolve(T: np.ndarray) -> Mapping[str, np.ndarray]:
        data = from_poses(robot_poses, T, cell.problem, setup=cell.setup, pairing=cell.pairing).data
        return solve(cell.problem, solver=solution.solver, backend=solution.backend, **data, **facts,
                     **options).unknowns

    try:
        focal = effect.answer_moves(resolve, solution.unknowns, names, T0, slopes, effect.focal_change(obs.camera))
        moves = None if obs.intrinsics_std is None else effect.answer_moves(
            resolve, solution.unknowns, names, T0, slopes, effect.one_sigma_moves(obs.intrinsics_std))
    except (HandEyeError, np.linalg.LinAlgError):  # a moved solve that fails: the answer as it is
        return solution
    diagnostics, note = dict(solution.diagnostics), None
    if moves is not None:
        percent, source = effect.focal_percent(obs.intrinsics_std, obs.camera), obs.intrinsics_std_from
        diagnostics, note = effect.with_moves(diagnostics, names, moves,
                                              lambda b, a: effect.growth_note(b, a, names, percent, source=source))
        diagnostics["intrinsics_effect"] = effect.focal_moves(moves, names, percent, source)
    diagnostics["focal_per_permille"] = effect.per_permille(focal, names)
    if note:
        diagnostics["warnings"] = [*diagnostics.get("warnings", []), note]
    return dataclasses.replace(solution, diagnostics=jsonable(diagnostics))
