"""The planar (4-DOF) mode of A_i X = Y B_i and A_i X = X B_i: a robot whose rotations share one axis.

When every rotation of the robot is about one axis (a SCARA, a mobile base, a pan-only head), the
translation of the hand-eye X along that axis is not determined by the data (Ulrich & Steger,
"Hand-eye calibration of SCARA robots using dual quaternions", Pattern Recognition and Image
Analysis 26, 2016):

- A_i X = X B_i: the motions rotate about one axis b (X's parent frame), so (I - R_Ai) b = 0 and
  t_X -> t_X + s b changes no motion's equation R_Ai t_X + t_Ai = R_X t_Bi + t_X.
- A_i X = Y B_i: with R_Ai = R_a(theta_i) R_0 (rotations about one base axis a), moving t_X by
  s R_0^T a (along the axis b = R_0^T a in the flange frame) and t_Y by s a together changes no
  pair's equation R_Ai t_X + t_Ai = R_Y t_Bi + t_Y, since R_Ai R_0^T a = a. Fixing either
  component fixes the pair.

The user gives that one number: ``tz_X`` = t_X . b (for AX=YB ``tz_Y`` = t_Y . a instead), b
the robot's common rotation axis in X's parent frame, signed so that its largest component is
positive (for a SCARA whose flange z is along the joint axes, simply t_X's z). The solvers with a
planar mode (`handeye.framework.solver.SolverSpec.planar_mode`) solve the other parameters with that
component fixed. docs/planar.md is the user's page.

Here, shared by both problems and by the planar solvers:
- `Planar`: what validated data carry in planar mode (which unknown, its axis, the value);
- detection (`for_axyb`, `for_axxb`): the spread of the robot's rotation axes (`main_axis`)
  below PLANAR_AXIS_SPREAD; the errors for a missing or superfluous tz; the refusal of a robot
  that only rotates about one fixed line (then even the rotation about the axis is undetermined);
- for solvers: the camera-side axis (`camera_axis`), least squares with one translation
  component fixed (`fixed_substitution`, `solve_fixed`, `axyb_translations`,
  `axxb_translation`);
- a SCARA-like simulator (`simulate_stations`, `simulate`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from handeye.base.errors import DegenerateDataError, InputError
from handeye.estimation.noise import NoiseModel
from handeye.geometry import so3_fast
from handeye.geometry.linalg import eigvalsh
from handeye.geometry.se3 import inverse, make_pose, so3_exp

#: Spread of the robot's rotation axes (rad, `main_axis`) below which the data are planar. The
#: translation along the axis enters the equations only through the tilt s of the axes,
#: |(I - R) a| ~ theta s, so it is determined to about sigma_t / (s theta sqrt(m)): at s = 1 deg,
#: rotations theta ~ 1 rad and the usual 0.1-0.5 mm of noise that is ~57 sigma_t / sqrt(m), several
#: mm, no better than a CAD value of the height. A planar robot's own noise (0.01-0.1 deg) tilts
#: its axes by far less than 1 deg, and calibration poses of a 6-axis arm spread them by tens of
#: degrees, so the threshold separates the two with a wide margin on both sides.
PLANAR_AXIS_SPREAD = math.radians(1.0)
#: from this many stations on, `for_axyb` first screens this many spread over the data: motions
#: between them turn about the axes the robot turns about, so a spread there is one in all
#: (0.1 s of a 1 s solve at 1e5 stations); only data that look planar there are looked at whole
SCREEN_STATIONS = 2000
#: rotations (rad) below which a motion has no axis
MIN_ROTATION = 1e-6
#: the flange moves as one rigid rotation about a fixed line when that model fits its in-plane
#: positions to this fraction of the data's RMS translation (rounding: ~1e-13; any real motion
#: or noise: far more): then the rotation about the axis is undetermined too
DEGENERATE_LINE = 1e-6
#: (problem, unknown) -> the frame the unknown's translation is expressed in, for messages
FRAMES = {("axyb", "X"): "the flange frame", ("axyb", "Y"): "the robot base frame",
          ("axxb", "X"): "the frame of the robot motions (the flange eye-in-hand, the robot base eye-to-hand)"}


@dataclasses.dataclass(frozen=True)
class Planar:
    """The planar mode of validated data: t_<unknown> . axis = value is given, not measured.

    unknown: "X" or "Y"; axis: (3,) unit, the robot's common rotation axis in the frame the
    unknown's translation is expressed in, largest component positive; value: in data units;
    spread: the spread of the robot's rotation axes (rad, `main_axis`); frame: that frame in
    words; coupled: the other unknown whose translation along the axis follows (AX=YB), or None.
    """

    unknown: str
    axis: np.ndarray
    value: float
    spread: float
    frame: str
    coupled: str | None = None

    @property
    def option(self) -> str:
        """The keyword the user gave: ``tz_X`` or ``tz_Y``."""
        return f"tz_{self.unknown}"

    def scaled(self, s: float) -> Planar:
        """The same mode for data whose translations are divided by s."""
        return dataclasses.replace(self, value=self.value / s)

    def fixed(self, unknowns: Sequence[str]) -> tuple[tuple[int, np.ndarray], ...]:
        """For `handeye.estimation.nlls.PoseModel.fixed`: ((index of the unknown, axis),), or () when the
        model has no such unknown."""
        return ((list(unknowns).index(self.unknown), self.axis),) if self.unknown in unknowns else ()

    def constrain(self, unknowns: Sequence[str], poses: Sequence[np.ndarray]) -> tuple[np.ndarray, ...]:
        """The poses with the fixed translation component set to the value (a start given by
        the user; the other components unchanged)."""
        out = [np.array(T, dtype=float) for T in poses]
        for j, axis in self.fixed(unknowns):
            out[j][:3, 3] += (self.value - float(out[j][:3, 3] @ axis)) * axis
        return tuple(out)

    def warning(self) -> str:
        """The warning every planar solve carries."""
        axis = ", ".join(f"{c:.3f}" for c in self.axis)
        text = (f"the translation of {self.unknown} along the robot's rotation axis (direction ({axis}) in "
                f"{self.frame}) is not determined by the data: it is the value you gave, {self.option} = "
                f"{self.value:.6g} (not measured)")
        if self.coupled:
            text += f"; {self.coupled}'s translation along the axis follows from it"
        return text

    def figures(self) -> dict[str, Any]:
        """JSON-ready description for diagnostics."""
        return {"fixed": self.option, "value": self.value, "axis": self.axis.tolist(),
                "axis_spread_deg": math.degrees(self.spread)}


# --------------------------------------------------------------------------- detection

def signed(v: np.ndarray) -> np.ndarray:
    """Unit vector along v with its largest component (in absolute value) positive."""
    v = np.asarray(v, dtype=float) / np.linalg.norm(v)
    return v if v[np.argmax(np.abs(v))] > 0 else -v


def main_axis(rotation_vectors: np.ndarray) -> tuple[np.ndarray | None, float]:
    """The axis rotations turn about (`signed`) and the spread of their axes about it (rad).

    With S = sum phi_i phi_i^T over the rotation vectors (each axis weighted by its angle squared,
    so that the noisy axis of a small motion counts little: the information a motion carries
    about the translation along the axis grows the same way) and its two largest eigenvalues
    l1 >= l2, the axis is the principal eigenvector and the spread 2 atan(sqrt(l2 / l1)): for two
    motions of equal angles the angle between their axes. (None, 0.0) when the rotations are
    below MIN_ROTATION altogether (sum of squared angles below its square).
    """
    S = _scatter(rotation_vectors)
    if S is None:
        return None, 0.0
    return signed(np.linalg.eigh(S)[1][:, 2]), _spread(S)


def _scatter(rotation_vectors: np.ndarray) -> np.ndarray | None:
    """S = sum phi_i phi_i^T (3, 3), None when the rotations are below MIN_ROTATION altogether."""
    phi = np.asarray(rotation_vectors, dtype=float).reshape(-1, 3)
    S = phi.T @ phi
    return None if np.trace(S) <= MIN_ROTATION**2 else S


def _spread(S: np.ndarray) -> float:
    """The spread of `main_axis` from S (eigenvalues only: the cheap test every validation runs)."""
    w = eigvalsh(S)
    return float(2.0 * np.arctan(np.sqrt(max(w[1], 0.0) / w[2])))


def take_facts(data: dict[str, Any], names: Sequence[str]) -> dict[str, float]:
    """Remove the facts `names` (``tz_X``, ...) from the raw fields `data` (the caller's own dict)
    and return those given (None counts as not given), checked: finite real numbers."""
    facts = {}
    for name in names:
        value = data.pop(name, None)
        if value is None:
            continue
        arr = np.asarray(value) if not isinstance(value, (str, bytes)) else None
        if arr is None or arr.shape != () or arr.dtype.kind not in "iuf" or not math.isfinite(float(arr)):
            raise InputError(f"{name} must be a finite number (a length in the data's unit), got {value!r}")
        facts[name] = float(arr)
    return facts


def for_axyb(A: np.ndarray, scale: float, facts: Mapping[str, float]) -> Planar | None:
    """The planar mode of A_i X = Y B_i with robot poses A: (m, 4, 4), or None (not planar, or
    no rotation at all: the problem's own checks refuse that). scale: the data's RMS translation.
    Raises DegenerateDataError (planar without tz, or a rotation about one fixed line) or
    InputError (tz on non-planar data, both tz_X and tz_Y)."""
    if len(A) > SCREEN_STATIONS:  # most data rotate about many axes: a spread sample says so
        sample = A[np.linspace(0, len(A) - 1, SCREEN_STATIONS).round().astype(int)]
        S = _scatter(so3_fast.consecutive_logs(sample))
        if S is not None and _spread(S) >= PLANAR_AXIS_SPREAD:
            _refuse(facts, _spread(S), "X and Y")
            return None
    S = _scatter(so3_fast.consecutive_logs(A))
    if S is None:
        return None
    spread = _spread(S)
    if spread >= PLANAR_AXIS_SPREAD:
        _refuse(facts, spread, "X and Y")
        return None
    axis_X = signed(np.linalg.eigh(S)[1][:, 2])
    axis_Y, _ = main_axis(so3_fast.consecutive_logs(A, moving=False))
    R = A[:, :3, :3]
    _one_line(R @ R[0].T, A[:, :3, 3], axis_Y, scale, absolute=True, what=(
        "the robot only rotates about one fixed line (the flange turns about the same axis at every pose and "
        "does not otherwise move across it), so the rotations of X and Y about that axis cannot be determined; "
        "record poses that also move the flange sideways, or that rotate about at least two different axes"))
    if not facts:
        raise DegenerateDataError(
            f"all robot motions rotate about one axis (a planar robot such as a SCARA; axis spread "
            f"{math.degrees(spread):.2g} deg), so the translations of X and Y along that axis cannot be determined "
            f"from these data (only together). Pass tz_X=<X's translation along the axis in your length unit> "
            f"(from CAD or a measurement; tz_X=0 to solve the other parameters; --tz-X on the command line), or "
            f"tz_Y for Y's, with solver "
            f"{_solvers('axyb')}; or record poses that rotate about at least two different axes")
    if len(facts) > 1:
        raise InputError("give one of tz_X and tz_Y, not both: fixing one translation along the axis determines the "
                         "other from the data")
    (name, value), = facts.items()
    unknown = name[-1]
    return Planar(unknown, axis_X if unknown == "X" else axis_Y, value, spread, FRAMES[("axyb", unknown)],
                  coupled="Y" if unknown == "X" else "X")


def for_axxb(A: np.ndarray, rotation_vectors: np.ndarray, scale: float, facts: Mapping[str, float]) -> Planar | None:
    """The planar mode of A_i X = X B_i with motions A: (m, 4, 4) and their rotation vectors
    (m, 3), or None; errors as `for_axyb`."""
    S = _scatter(rotation_vectors)
    if S is None:
        return None
    spread = _spread(S)
    if spread >= PLANAR_AXIS_SPREAD:
        _refuse(facts, spread, "X")
        return None
    axis = signed(np.linalg.eigh(S)[1][:, 2])
    _one_line(A[:, :3, :3], A[:, :3, 3], axis, scale, absolute=False, what=(
        "the robot motions all rotate about one line (the flange turns about the same fixed axis and does not "
        "otherwise move across it), so these data do not determine X's rotation about that axis; record "
        "motions that also move the flange sideways, or that rotate about at least two different axes"))
    if not facts:
        raise DegenerateDataError(
            f"the robot motions rotate about parallel axes (a planar robot such as a SCARA; axis spread "
            f"{math.degrees(spread):.2g} deg), so these data do not determine X's translation along that axis. "
            f"Pass tz_X=<its value in your length unit> (from CAD or a measurement; tz_X=0 to solve the other "
            f"five parameters; --tz-X on the command line) with solver {_solvers('axxb')}; or record motions that "
            "rotate about at least two different axes")
    return Planar("X", axis, facts["tz_X"], spread, FRAMES[("axxb", "X")])


def _refuse(facts: Mapping[str, float], spread: float, what: str) -> None:
    if facts:
        name = next(iter(facts))
        raise InputError(
            f"{name} is given, but the robot's rotation axes spread by {math.degrees(spread):.3g} deg (not a planar "
            f"robot: {math.degrees(PLANAR_AXIS_SPREAD):.3g} deg or more), so the data determine the translations of "
            f"{what} along every axis; do not pass {name}")


def _one_line(R: np.ndarray, t: np.ndarray, axis: np.ndarray, scale: float, absolute: bool, what: str) -> None:
    """Raise DegenerateDataError(what) when the poses (absolute=True: R_k R_0^T and t_k of the
    stations) or motions (R_i, t_i) are rotations about one fixed line parallel to `axis`:
    in complex coordinates z of the plane normal to the axis and signed angles theta about it,
    stations then satisfy z_k = e^(i theta_k) u + v and motions z_i = (1 - e^(i theta_i)) p for
    constants u, v, p (translations along the axis do not matter). Tested by the residual of that
    least-squares fit against DEGENERATE_LINE times the data's RMS translation."""
    E = np.linalg.qr(axis[:, None], mode="complete")[0][:, 1:]  # (3, 2): the plane normal to the axis
    turned = R @ E[:, 0]  # each rotation applied to the plane's first direction
    theta = np.arctan2(turned @ E[:, 1], turned @ E[:, 0])
    z = t @ E[:, 0] + 1j * (t @ E[:, 1])
    rot = np.exp(1j * theta)
    design = np.stack([rot, np.ones_like(rot)], axis=1) if absolute else (1.0 - rot)[:, None]
    coef = np.linalg.lstsq(design, z, rcond=None)[0]
    residual = float(np.sqrt(np.mean(np.abs(design @ coef - z) ** 2)))
    if residual <= DEGENERATE_LINE * scale:
        raise DegenerateDataError(what)


def _solvers(problem: str) -> str:
    """The registered solvers with a planar mode, in words ("auto, kron-lstsq or refine")."""
    from handeye.host.registry import get_registry

    registry = get_registry()
    names = [n for n in registry.solver_names(problem) if registry.solver(n, problem).planar_mode]
    if not names:
        return "(none registered)"
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"


# --------------------------------------------------------------------------- for solvers

def camera_axis(robot_vectors: np.ndarray, camera_vectors: np.ndarray, robot_axis: np.ndarray) -> np.ndarray | None:
    """The camera-side axis c of paired motions (rotation vectors (n, 3) each, paired by row)
    with R c = robot_axis for the unknown rotation R that conjugates them (phi_camera = R^T
    phi_robot): `main_axis` of the camera's, signed to agree with the robot's motion by motion."""
    c, _ = main_axis(camera_vectors)
    if c is None:
        return None
    return c if float(np.sum((robot_vectors @ robot_axis) * (camera_vectors @ c))) >= 0 else -c


def axis_rows(c: np.ndarray, b: np.ndarray, weight: float, n: int, start: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows E beta = d (weighted) stating M c = b for the 3x3 block M = beta[start:start+9]
    (column-major vec, as the Kronecker systems): E: (3, n) = weight (c^T kron I3), d = weight b."""
    E = np.zeros((3, n))
    E[:, start:start + 9] = weight * np.kron(c[None, :], np.eye(3))
    return E, weight * b


def fixed_substitution(n: int, index: int, axis: np.ndarray, value: float) -> tuple[np.ndarray, np.ndarray]:
    """beta = z0 + T y with y free: (T (n, n-1), z0 (n,)) parametrise exactly the beta whose
    3-block beta[index:index+3] has axis . block = value (T: identity, with the block's columns
    replaced by an orthonormal basis of the plane normal to the axis)."""
    T = np.delete(np.eye(n), index + 2, axis=1)
    T[index:index + 3, index:index + 2] = np.linalg.qr(axis[:, None], mode="complete")[0][:, 1:]
    z0 = np.zeros(n)
    z0[index:index + 3] = value * axis
    return T, z0


def solve_fixed(N: np.ndarray, rhs: np.ndarray, index: int, axis: np.ndarray, value: float) -> np.ndarray:
    """z minimising 1/2 z^T N z - rhs^T z with axis . z[index:index+3] = value (N positive
    definite on that subspace); DegenerateDataError when it is not."""
    from scipy.linalg import LinAlgError, solve

    T, z0 = fixed_substitution(len(rhs), index, axis, value)
    try:
        y = solve(T.T @ N @ T, T.T @ (rhs - N @ z0), assume_a="pos")
    except LinAlgError:
        raise DegenerateDataError("the translations cannot be determined from these data, even with the one along the "
                                  "rotation axis given: record poses that move the flange across the axis") from None
    return z0 + T @ y


def axyb_translations(data: Any, RX: np.ndarray, RY: np.ndarray, planar: Planar) -> tuple[np.ndarray, np.ndarray]:
    """`handeye.problems.axyb.solve_translations` (the same 6x6 normal equations of
    [R_Ai, -I] [t_X; t_Y] = R_Y t_Bi - t_Ai) with planar.unknown's component along the axis fixed."""
    sums = data.translation_sums
    N = np.block([[sums.GA, -sums.sum_RA.T], [-sums.sum_RA, sums.m * np.eye(3)]])
    rhs = np.concatenate([sums.RAt_R_tB(RY) - sums.RAt_tA, sums.sum_tA - RY @ sums.sum_tB])
    t = solve_fixed(N, rhs, 0 if planar.unknown == "X" else 3, planar.axis, planar.value)
    return t[:3], t[3:]


def axxb_translation(data: Any, RX: np.ndarray, planar: Planar) -> np.ndarray:
    """`handeye.problems.axxb.solve_translation` ((I - R_Ai) t_X = t_Ai - R_X t_Bi) with t_X's
    component along the axis fixed."""
    sums = data.translation_sums
    D = data.m * np.eye(3) - sums.sum_RA - sums.sum_RA.T + sums.GA
    rhs = sums.sum_tA - sums.RAt_tA - RX @ sums.sum_tB + sums.RAt_R_tB(RX)
    return solve_fixed(D, rhs, 0, planar.axis, planar.value)


# --------------------------------------------------------------------------- simulation

#: the simulator's hand-eye X = T_flange_cam: a camera looking along the flange z, 60 mm along it
#: (tz_X = 60: the flange z is the joint axis)
PLANAR_X = make_pose(so3_exp([0.05, -0.08, 0.6]), [30.0, -20.0, 60.0])
#: ... and Y = T_base_target: a board on the table, tilted a little (tz_Y = -20)
PLANAR_Y = make_pose(so3_exp([0.03, 0.04, 0.4]), [400.0, 50.0, -20.0])


def simulate_stations(stations: int, *, seed: int | None = None, noise: NoiseModel | None = None,
                      X: np.ndarray | None = None, Y: np.ndarray | None = None,
                      heights: tuple[float, float] = (150.0, 250.0)) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """A SCARA-like eye-in-hand cell (mm): ({"A": T_base_flange, "B": T_target_cam} of `stations`
    stations, {"X", "Y"}).

    The flange rotates about the base z only: R_A = R_z(theta) diag(1, -1, -1) (flange z pointing
    down, along the joint axis), theta uniform in [-pi, pi); its position is uniform in a ring
    250-550 mm around the base within +-120 deg, at a height uniform in `heights`. B = Y^-1 A X,
    then noise (`NoiseModel`: "A" on the robot, "B" on the camera), which tilts the robot's axes
    by its rotation noise. X, Y default to PLANAR_X, PLANAR_Y; tz_X = X[2, 3], tz_Y = Y[2, 3]
    (the axis is +z in both frames).
    """
    if stations < 2:
        raise InputError(f"stations must be >= 2, got {stations}")
    rng = np.random.default_rng(seed)
    X = PLANAR_X if X is None else np.asarray(X, dtype=float)
    Y = PLANAR_Y if Y is None else np.asarray(Y, dtype=float)
    theta = rng.uniform(-np.pi, np.pi, stations)
    radius, bearing = rng.uniform(250.0, 550.0, stations), rng.uniform(-2.0 * np.pi / 3, 2.0 * np.pi / 3, stations)
    height = rng.uniform(heights[0], heights[1], stations)
    R = so3_exp(np.outer(theta, [0.0, 0.0, 1.0])) @ np.diag([1.0, -1.0, -1.0])
    A = make_pose(R, np.stack([radius * np.cos(bearing), radius * np.sin(bearing), height], axis=1))
    B = inverse(Y) @ A @ X
    noise = noise or NoiseModel()
    noise_rng = np.random.default_rng(rng.integers(2**63))
    return {"A": noise.apply("A", A, noise_rng), "B": noise.apply("B", B, noise_rng)}, {"X": np.array(X), "Y": np.array(Y)}


def simulate(problem: str, stations: int, *, pairing: str = "all", **options: Any) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Data of `problem` from `simulate_stations` (options passed on): ``axyb`` the stations'
    pairs and {"X", "Y"}; ``axxb`` their relative motions (`handeye.problems.axxb.relative_motions`,
    `pairing`) and {"X"}."""
    data, truth = simulate_stations(stations, **options)
    if problem == "axyb":
        return data, truth
    if problem == "axxb":
        from handeye.geometry.motions import relative_motions

        A, B = relative_motions(data["A"], data["B"], pairing)
        return {"A": A, "B": B}, {"X": truth["X"]}
    raise InputError(f"problem {problem!r} has no planar simulation; use 'axyb' or 'axxb'")
