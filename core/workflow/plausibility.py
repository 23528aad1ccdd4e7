"""Plausibility of a calibration from absolute poses, and the setup mistake that explains an
implausible one.

A solver's status says it solved *its* problem; it cannot say the data were the data the user
meant. The common setup mistakes (robot angles read in another Euler order, camera or robot
poses inverted, the other setup, pairs shifted by one station, a camera unit off by 1000) all
give a solution with status ``optimal`` whose residuals (eqs. 32-33) are 10-100x the data's noise.
Every "RMS" below is a trimmed RMS, over the `TRIM_KEEP` (80%) smallest residuals: a setup
mistake raises every pair's residual, while a few gross pairs (which `auto` lists and leaves
out) must not make a good fit, or the closed-form fits compared in part 2, look implausible.
`check` decides whether the residuals are plausible and names the mistake that explains them.

The statistic (docs/calibrate.md, "Plausibility checks"), two parts:

1. **Physical floor.** The residual RMS over the pairs (rotation angle and translation distance
   between the two sides of the equation) against limits no calibrated cell reaches: a robot's
   flange pose and a camera's board pose are rarely off by more than 0.5 deg / a few mm per pose,
   and ten times the accuracy study's noise (camera 1.15 deg / 5 mm per axis, the worst case we
   accept without alarm) gives residual RMS up to ~2.5 deg / 12 mm over stations (axyb) and
   ~3.2 deg / 18 mm over motions (axxb, two stations' noise each). A fit is implausible when the
   rotation RMS exceeds `ROT_LIMIT_DEG` (6 deg) or the translation RMS exceeds
   `TRANS_LIMIT_FRACTION` (12%) of the cell's size (the RMS distance of the flange positions
   from their centroid: the lever arms scale with it; the simulated cell's is 220-320 mm, so
   the limit is 26-38 mm).
2. **A better explanation.** Every usual mistake is undone on the raw streams and solved with a
   cheap closed form (the problem's `Problem.quick_solver`, kron-lstsq for the built-ins, else its
   first start); the as-given data is solved the same way. A problem says which of the mistakes
   (`handeye.framework.problem_cell.MISTAKES`) may be tried on its stations (`Problem.mistakes`).
   A hypothesis *explains* the data when its score (the larger of the two RMS, each divided by
   its limit) is below 1 (plausible) and at least `EXPLAIN_FACTOR` (4) times lower than the
   as-given data's. Noise cannot do that: a wrong model never fits noisy data better than the
   right one by more than the few degrees of freedom it drops (shifting pairs drops one
   station), so on clean data the best hypothesis ratio stays near or below 1.
   On a long stream (from 2 x `SCREEN_STATIONS` stations) every hypothesis is first fitted on
   `SCREEN_STATIONS` stations evenly spaced over the sequence, and on all stations only where it
   may explain the data there (`_scored_hypotheses`): a fit costs time in proportion to the
   stations (AX=XB's default pairing: to their square), and 20-30 hypotheses fitted on 500
   stations took 10-20 s. The verdict and the mistakes named are those of the deciding fits,
   on all stations up to `FULL_STATIONS` and on that many evenly spaced beyond.

The fit is unreliable when part 1 fails or part 2 finds an explanation. Nothing is switched:
the caller keeps the user's answer and reports `Status.UNRELIABLE` with the message.

Also (`handeye.checks.stations`): duplicated stations (two robot poses within `DUPLICATE_DEG` and `DUPLICATE_FRACTION` of the
cell size) and fewer than `MIN_STATIONS_FOR_SIGMA` stations (the 1-sigma from the covariance of
the fit is not meaningful) are warnings that do not change the status.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from handeye.base.errors import DegenerateDataError, HandEyeError
from handeye.checks.stations import cell_size, station_warnings
from handeye.geometry.se3 import inverse

#: residual rotation RMS (deg) no calibrated cell reaches
ROT_LIMIT_DEG = 6.0
#: residual translation RMS, as a fraction of the cell size (`cell_size`: the cell's lever arm)
TRANS_LIMIT_FRACTION = 0.12
#: a hypothesis explains the data when it lowers the score by this factor to below 1
EXPLAIN_FACTOR = 4.0
#: other explaining mistakes within this factor of the best score are named too: some are the same
#: data (axyb: camera poses inverted = the other setup = robot poses inverted with X and Y swapped;
#: an axxb cell fits both its camera poses inverted and the other setup); a wrong hypothesis
#: scores >= ~10 on the simulator
ALTERNATIVE_FACTOR = 10.0
#: camera-to-board distances (m, median over the stations) a calibration can have: a unit
#: hypothesis outside them is not tried
VIEW_DISTANCE_M = (0.02, 50.0)
#: long streams: the hypotheses are first fitted on this many stations evenly spaced over the
#: sequence (`screen_rows`, from twice as many stations on; 0: never), and on all stations only
#: where they may explain the data there (`_scored_hypotheses`). Measured (bench/large_files.py,
#: AX=XB, 500 stations, a loaded machine): a clean file 0.65 s instead of 12.4 s on all stations,
#: inverted camera poses 3.3 s instead of 6.4 s (three hypotheses explain them), same verdicts.
SCREEN_STATIONS = 40
#: ... and the fits that decide (the as-given data's, and a hypothesis that may explain them) on at
#: most this many stations evenly spaced over the sequence: a trimmed RMS over 200 stations is
#: known to a few per cent, while AX=XB's default pairing of every two of 500 stations makes
#: 124,750 motions to validate and fit (measured, 500 stations with the camera poses inverted:
#: 1.9-3.3 s for the check before, most of it four such fits)
FULL_STATIONS = 200
#: a screening fit may explain the data on all stations when its score is below this, and its
#: ratio above EXPLAIN_FACTOR divided by it: a fit on 40 stations scores within ~30% of the
#: fit on all on the simulator, so this leaves a wide margin
SCREEN_MARGIN = 3.0
#: the Tait-Bryan sequences (scipy: lower case extrinsic, upper case intrinsic)
TAIT_BRYAN = tuple("".join(p) for p in itertools.permutations("xyz")) + tuple(
    "".join(p) for p in itertools.permutations("XYZ"))


@dataclasses.dataclass(frozen=True)
class Streams:
    """The raw streams of a calibration and how they were turned into the problem's data.

    robot: (n, 4, 4) T_base_flange as read; camera: (n, 4, 4) T_cam_target as read, in the robot's
    unit; unit: the robot's length unit (for messages); setup, problem, pairing: as solved.
    reread_robot / reread_camera: for Euler formats, a function seq -> (n, 4, 4) that reads the
    same file's numbers with another scipy Euler sequence (None: no Euler hypotheses);
    robot_format / camera_format / camera_unit: the names the user gave (for the suggestions).
    facts: facts about the cell given besides the poses (``tz_X`` of a planar robot,
    `handeye.problems.planar`), passed to the fits of data that need them.
    """

    robot: np.ndarray
    camera: np.ndarray
    unit: str
    setup: str
    problem: str
    pairing: str | None = None
    robot_format: str | None = None
    camera_format: str | None = None
    camera_unit: str | None = None
    reread_robot: Callable[[str], np.ndarray] | None = None
    reread_camera: Callable[[str], np.ndarray] | None = None
    facts: Mapping[str, float] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class Hypothesis:
    """One usual mistake undone: what it says in the user's words, the flags that would express
    it, and the residual RMS (rotation deg, translation in the robot unit) of its closed-form fit."""

    description: str
    suggestion: str
    rotation_deg: float
    translation: float
    score: float
    ratio: float
    #: the stations of the fit when it was screened on a subsample only and could not explain
    #: the data there, or when a long stream's deciding fit took FULL_STATIONS of them
    #: (`_scored_hypotheses`); None: fitted on all stations
    stations: int | None = None


@dataclasses.dataclass(frozen=True)
class Report:
    """What `check` found. plausible: the fit passes both parts; rotation_deg, translation: the
    solution's residual RMS; limits: (ROT_LIMIT_DEG, translation limit); explanation: the best
    hypothesis that explains the data (or None); warnings: messages for the user (the
    implausibility message first, then duplicates and few stations)."""

    plausible: bool
    rotation_deg: float
    translation: float
    cell_size: float
    limits: tuple[float, float]
    baseline: tuple[float, float] | None
    explanation: Hypothesis | None
    hypotheses: tuple[Hypothesis, ...]
    warnings: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        return {
            "plausible": self.plausible,
            "residual_rms": {"rotation_deg": self.rotation_deg, "translation": self.translation},
            "limits": {"rotation_deg": self.limits[0], "translation": self.limits[1]},
            "cell_size": self.cell_size,
            "baseline": None if self.baseline is None else {
                "rotation_deg": self.baseline[0], "translation": self.baseline[1],
                "score": max(self.baseline[0] / self.limits[0], self.baseline[1] / self.limits[1])},
            "explanation": None if self.explanation is None else dataclasses.asdict(self.explanation),
            "hypotheses": [dataclasses.asdict(h) for h in self.hypotheses],
        }


#: share of the smallest residuals the RMS is taken over (module docstring)
TRIM_KEEP = 0.8


def _rms(values: Any) -> float:
    """RMS of the TRIM_KEEP smallest of `values` (all of them for fewer than 5)."""
    squares = np.sort(np.asarray(values, dtype=float).ravel() ** 2)
    keep = len(squares) if len(squares) < 5 else max(1, int(np.ceil(TRIM_KEEP * len(squares))))
    return float(np.sqrt(np.mean(squares[:keep])))


def _fit(streams: Streams, robot: np.ndarray, camera: np.ndarray, setup: str) -> tuple[float, float] | None:
    """Residual RMS (deg, unit) of the closed-form fit of these streams, None if it fails. The
    facts of the streams (a planar robot's tz_X) are passed to data that need them (a hypothesis
    may make the robot's rotations planar or not); they do not change the residuals. The data
    are validated once and solved without the host's self-check (`run_registered`): only the
    answer's residuals are wanted, and the self-check and a second validation cost as much as
    the fit (the answer is the same as `handeye.solve`'s)."""
    from handeye.framework.threads import one_blas_thread
    from handeye.host.api import run_registered
    from handeye.host.registry import get_registry
    from handeye.io.data_files import from_poses

    try:
        pose_file = from_poses(robot, camera, streams.problem, setup=setup, pairing=streams.pairing)
        problem = get_registry().problem(streams.problem)
        with one_blas_thread():
            try:
                data = problem.validate(**pose_file.data)
            except DegenerateDataError:
                if not streams.facts:
                    raise
                data = problem.validate(**pose_file.data, **streams.facts)
        sol = run_registered(hypothesis_solver(problem), data, problem=streams.problem)
        res = problem.residuals(data, sol.unknowns)
    except (HandEyeError, np.linalg.LinAlgError, ValueError):
        return None
    return math.degrees(_rms(res["rotation"])), _rms(res["translation"])


def hypothesis_solver(problem: Any) -> str:
    """The solver of the closed-form fits: the problem's `Problem.quick_solver`, else its first
    start (`Problem.starts`), else ``auto``."""
    return problem.quick_solver or (problem.starts[0] if problem.starts else "auto")


def _camera_can_see(camera: np.ndarray, unit: str) -> bool:
    """Whether the camera-to-board distances of T_cam_target `camera` (n, 4, 4), in `unit`, are
    ones a camera calibrates from (median within VIEW_DISTANCE_M): a unit hypothesis that puts the
    board 3 mm or 3 km from the camera is no explanation, however well it fits (a far board seen
    from few stations fits almost anything once its translations shrink to millimetres)."""
    metres = float(np.median(np.linalg.norm(camera[:, :3, 3], axis=1))) * (1e-3 if unit == "mm" else 1.0)
    return VIEW_DISTANCE_M[0] <= metres <= VIEW_DISTANCE_M[1]


def _hypotheses(s: Streams) -> list[tuple[str, str, np.ndarray, np.ndarray, str]]:
    """(description, suggestion, robot, camera, setup) of each usual mistake undone that the
    problem lets the check try (`Problem.mistakes`)."""
    from handeye.host.registry import get_registry

    tried = set(get_registry().problem(s.problem).mistakes)
    other = "eye-to-hand" if s.setup == "eye-in-hand" else "eye-in-hand"
    out: list[tuple[str, str, np.ndarray, np.ndarray, str]] = []
    if "camera-inverted" in tried:
        out.append((("the camera poses are inverted (T_target_cam, the camera's pose in the board, instead of "
                     "T_cam_target)"), "invert the camera poses (`camera.poses: camera-in-board`)", s.robot,
                    inverse(s.camera), s.setup))
    if "robot-inverted" in tried:
        out.append(("the robot poses are inverted (T_flange_base instead of T_base_flange)",
                    "invert the robot poses before calibrating", inverse(s.robot), s.camera, s.setup))
    if "other-setup" in tried:
        out.append((f"the setup is {other}", f"`setup: {other}`", s.robot, s.camera, other))
    n = len(s.robot)
    if n >= 4 and "shifted" in tried:
        out += [
            ("the camera file starts one station late (its row k is the station of robot row k+1)",
             "drop the first robot row and the last camera row", s.robot[1:], s.camera[:-1], s.setup),
            ("the camera file starts one station early (its row k+1 is the station of robot row k)",
             "drop the first camera row and the last robot row", s.robot[:-1], s.camera[1:], s.setup),
        ]
    other_unit = {"mm": "m", "m": "mm"}
    for factor, word, true_unit in ((1e-3, "1000 times too large", "mm"), (1e3, "1000 times too small", "m")):
        if "camera-unit" not in tried:
            break
        cam = np.array(s.camera)
        cam[:, :3, 3] *= factor
        if not _camera_can_see(cam, s.unit):  # the board would sit a few mm, or kilometres, from the camera
            continue
        if s.camera_unit is not None and other_unit[s.camera_unit] == true_unit:
            text = f"the camera file is in {true_unit}, not {s.camera_unit}"
            sugg = f"`camera.unit: {true_unit}`"
        else:
            text = f"the camera translations are {word}"
            sugg = "check the camera file's length unit (`camera.unit`) and the robot's (`robot.unit`)"
        out.append((text, sugg, s.robot, cam, s.setup))
    for which, reread, fmt in (("robot", s.reread_robot, s.robot_format), ("camera", s.reread_camera, s.camera_format)):
        if reread is None or "euler" not in tried:
            continue
        current = _seq_of(fmt)
        for seq in TAIT_BRYAN:
            if seq == current:
                continue
            try:
                poses = reread(seq)
            except HandEyeError:
                continue
            kind = "extrinsic, fixed axes" if seq.islower() else "intrinsic, moving axes"
            robot, camera = (poses, s.camera) if which == "robot" else (s.robot, poses)
            out.append((f"the {which} angles are Euler {seq} ({kind})", _euler_flag(which, seq, fmt),
                        robot, camera, s.setup))
    return out


def _euler_flag(which: str, seq: str, fmt: str | None) -> str:
    """```robot.format: euler:SEQ:deg``` in the angle unit of `fmt`, with the presets of that sequence
    (a cell's setting: the command line shows its flag, ``--robot-format euler:SEQ:deg``)."""
    from handeye.io.pose_formats import PRESETS, parse_format

    try:
        degrees = parse_format(fmt).degrees if fmt else True
    except HandEyeError:
        degrees = True
    flag = f"`{which}.format: euler:{seq}:{'rad' if degrees is False else 'deg'}`"
    presets = [name for name, f in PRESETS.items() if f.kind == "euler" and f.seq == seq]
    return flag + (f", as the preset{'s' if len(presets) > 1 else ''} {' / '.join(presets)}" if presets else "")


def _seq_of(fmt: str | None) -> str | None:
    if fmt is None:
        return None
    from handeye.io.pose_formats import parse_format

    try:
        return parse_format(fmt).seq
    except HandEyeError:
        return None


def check(streams: Streams, residuals: Mapping[str, np.ndarray], *, hypotheses: bool = True) -> Report:
    """Whether the fit whose per-pair `residuals` ({"rotation": rad, "translation": unit}) the
    solver left on `streams` is plausible (module docstring), and which usual mistake explains
    it; with hypotheses=False only the physical floor (part 1) is tested."""
    rot = math.degrees(_rms(residuals["rotation"]))
    trans = _rms(residuals["translation"])
    size = cell_size(streams.robot, streams.camera)
    trans_limit = TRANS_LIMIT_FRACTION * size if size > 0 else math.inf

    def score(r: float, t: float) -> float:
        return max(r / ROT_LIMIT_DEG, t / trans_limit)

    floor_ok = score(rot, trans) <= 1.0
    full = full_rows(len(streams.robot))
    baseline = _fit(streams, streams.robot[full], streams.camera[full], streams.setup) if hypotheses else None
    found: list[Hypothesis] = []
    if baseline is not None:
        found = _scored_hypotheses(streams, score, max(score(*baseline), score(rot, trans)), score(rot, trans))
        found.sort(key=lambda h: float(f"{h.score:.4g}"))  # stable: equivalent mistakes keep their order
    explaining = [h for h in found if h.score < 1.0 and h.ratio >= EXPLAIN_FACTOR]
    best = explaining[0] if explaining else None
    warnings: list[str] = []
    unit = streams.unit
    if best is not None or not floor_ok:
        head = (f"implausible fit: residual RMS {rot:.3g} deg / {trans:.3g} {unit} (limits {ROT_LIMIT_DEG:g} deg / "
                f"{trans_limit:.3g} {unit} = {TRANS_LIMIT_FRACTION:.0%} of the cell size {size:.3g} {unit})")
        if best is not None:
            same = [h for h in explaining[1:] if h.score <= ALTERNATIVE_FACTOR * best.score]
            alts = "".join(f"; or {h.description} ({h.suggestion})" for h in same)
            head = (f"implausible fit: residuals drop from {rot:.3g} deg / {trans:.3g} {unit} to "
                    f"{best.rotation_deg:.3g} deg / {best.translation:.3g} {unit} if {best.description}: "
                    f"did you mean that? ({best.suggestion}{alts}). The answer printed is for the data as given "
                    "and is not to be used")
        else:
            head += ("; none of the usual mistakes (Euler order, inverted camera or robot poses, other setup, "
                     "pairs shifted by one, camera unit x1000) explains it: check the pairing of the files, "
                     "the formats and the units")
        warnings.append(head)
    warnings += station_warnings(streams.robot, unit)
    return Report(floor_ok and best is None, rot, trans, size, (ROT_LIMIT_DEG, trans_limit), baseline, best,
                  tuple(found), tuple(warnings))


def screen_rows(n: int) -> np.ndarray | None:
    """The rows of a stream of n stations the hypotheses are screened on (`_scored_hypotheses`):
    SCREEN_STATIONS rows evenly spaced over the sequence, first and last included; None (fit on
    all) below twice that many stations, where screening would save little, or when
    SCREEN_STATIONS is 0. Evenly spaced rows are an unbiased sample of the stations (the trimmed
    RMS of a fit on them estimates the full fit's), deterministic, and spread over the recorded
    trajectory, whose consecutive stations are near each other."""
    k = SCREEN_STATIONS
    if not k or n < 2 * k:
        return None
    return _spread(n, k)


def _spread(n: int, k: int) -> np.ndarray:
    """k rows of n evenly spaced, the first and the last included."""
    return np.unique(np.linspace(0, n - 1, k).round().astype(np.intp))


def full_rows(n: int) -> np.ndarray | slice:
    """The rows of a stream of n stations its deciding fits use: all of them up to FULL_STATIONS,
    else FULL_STATIONS evenly spaced (as `screen_rows`)."""
    return slice(None) if n <= FULL_STATIONS else _spread(n, FULL_STATIONS)


def _may_explain(s: float, ratio: float) -> bool:
    """Whether a hypothesis whose screening fit scores s, ratio may explain the data on all
    stations (score below 1, ratio at least EXPLAIN_FACTOR), within the screen's margin."""
    return s < SCREEN_MARGIN and ratio >= EXPLAIN_FACTOR / SCREEN_MARGIN


def _scored_hypotheses(streams: Streams, score: Callable[[float, float], float], base_score: float,
                       solution_score: float) -> list[Hypothesis]:
    """Every hypothesis of `_hypotheses`, fitted and scored against the as-given data's
    `base_score` (that of the fit on all stations).

    On a long stream (`screen_rows`) every hypothesis, and the as-given data, is first fitted on
    the screening rows only; a hypothesis is fitted on all stations when it may explain the data
    there (`_may_explain`, its ratio taken against the as-given data's fit on the same rows) or
    when its screening fit fails (the rows may not determine what all stations do). The others
    keep their screening figures (`Hypothesis.stations`): they score several times worse than a
    fit that explains, so that neither the verdict nor the alternatives named can change. A fit
    costs time proportional to the stations (to their square for AX=XB's default pairing of
    every two stations), and with 20-30 hypotheses this is what makes large files affordable."""
    out: list[Hypothesis] = []
    n = len(streams.robot)
    rows = screen_rows(n)
    screen_base = None
    if rows is not None:
        fit = _fit(streams, streams.robot[rows], streams.camera[rows], streams.setup)
        screen_base = None if fit is None else max(score(*fit), solution_score)
    for text, sugg, robot, camera, setup in _hypotheses(streams):
        sub = screen_rows(len(robot)) if screen_base is not None else None
        if sub is not None:
            fit = _fit(streams, robot[sub], camera[sub], setup)
            if fit is not None and not _may_explain(score(*fit), screen_base / max(score(*fit), 1e-300)):
                s = score(*fit)
                out.append(Hypothesis(text, sugg, fit[0], fit[1], s, base_score / max(s, 1e-300), len(sub)))
                continue
        full = full_rows(len(robot))
        fit = _fit(streams, robot[full], camera[full], setup)
        if fit is not None:
            s = score(*fit)
            out.append(Hypothesis(text, sugg, fit[0], fit[1], s, base_score / max(s, 1e-300),
                                  None if isinstance(full, slice) else len(full)))
    return out
