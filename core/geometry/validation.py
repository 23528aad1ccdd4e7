"""Validation of pose stacks shared by every problem.

`pose_stack` turns user input (array or sequence of 4x4) into a read-only float64 copy of shape
(m, 4, 4) after checking that every entry is a rigid motion: finite, last row [0, 0, 0, 1],
rotation block orthonormal to `ORTHONORMALITY_TOL` with det +1. `float_array` is its conversion,
which refuses what numpy would convert wrongly (complex numbers, masked arrays, None, text).
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from handeye.base.errors import DegenerateDataError, InputError
from handeye.geometry.linalg import det, einsum, median
from handeye.geometry.se3 import ORTHONORMALITY_TOL, orthonormality_error

LAST_ROW_TOL = 1e-9
#: what a pose stack is, for messages
POSE_STACK = "an array of 4x4 poses with shape (m, 4, 4)"


def pose_stack(value: Any, name: str, *, tol: float = ORTHONORMALITY_TOL) -> np.ndarray:
    """Validated read-only copy of `value` as (m, 4, 4) float64.  Raises InputError naming `name`."""
    T = _float_copy(value, name)
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise InputError(f"expected {name} to have shape (m, 4, 4), got {T.shape}")
    bad = ~np.all(np.isfinite(T), axis=(1, 2))
    if bad.any():
        raise InputError(f"{name} contains NaN or inf in pose(s) {_indices(bad)}")
    bad = np.any(np.abs(T[:, 3, :] - (0.0, 0.0, 0.0, 1.0)) > LAST_ROW_TOL, axis=1)
    if bad.any():
        raise InputError(f"{name}: last row must be [0, 0, 0, 1]; it is not in pose(s) {_indices(bad)}")
    R = T[:, :3, :3]
    err = orthonormality_error(R)
    bad = err > tol
    if bad.any():
        raise InputError(
            f"{name}: rotation block is not orthonormal (max |R^T R - I| = {err.max():.1e} > "
            f"tolerance {tol:g}) in pose(s) {_indices(bad)}; re-orthonormalise the data or check "
            "its units and layout (row-major 4x4 expected)"
        )
    bad = np.sum(R[:, :, 0] * np.cross(R[:, :, 1], R[:, :, 2]), axis=1) < 0  # det(R)
    if bad.any():
        raise InputError(f"{name}: rotation block has det -1 (a reflection) in pose(s) {_indices(bad)}")
    T[:, 3, :] = (0.0, 0.0, 0.0, 1.0)
    T.setflags(write=False)
    return T


def _is_complex(value: Any) -> bool:
    try:
        return bool(np.iscomplexobj(value))
    except (TypeError, ValueError):
        return False


def is_masked(value: Any) -> bool:
    """Whether `value` is a numpy masked array with at least one masked entry (converting it
    would keep the values under the mask, ignoring it)."""
    return isinstance(value, np.ma.MaskedArray) and bool(np.ma.getmaskarray(value).any())


def masked_count(value: np.ma.MaskedArray) -> str:
    """"1 masked entry", "3 masked entries": how many entries of a masked array are masked."""
    count = int(np.ma.getmaskarray(value).sum())
    return f"{count} masked {'entry' if count == 1 else 'entries'}"


def float_array(value: Any, name: str, expected: str) -> np.ndarray:
    """A float64 copy of `value`, or InputError naming `name` and what was `expected` (e.g. "an
    array of 4x4 poses with shape (m, 4, 4)"): for None (a JSON null), complex numbers (their
    imaginary part would be dropped silently), masked arrays with masked entries (the mask would
    be ignored), text, mappings and other non-numbers, and numbers beyond float64."""
    if value is None:
        raise InputError(f"{name} has no value (None); expected {expected}")
    if _is_complex(value):
        raise InputError(f"{name} holds complex numbers; expected {expected} with real entries "
                         "(an imaginary part would be dropped)")
    if is_masked(value):
        what = ("remove the poses with masked entries from every stack (the pairs must stay aligned)"
                if expected == POSE_STACK else "remove or fill the masked entries")
        raise InputError(f"{name} is a masked array with {masked_count(value)}, and masks are not used: "
                         f"{what} and pass a plain array")
    if isinstance(value, np.ndarray) and value.dtype.kind in "US":
        raise InputError(f"{name} is an array of text ({value.dtype}); expected {expected}: convert the "
                         "numbers when reading them (e.g. np.loadtxt, or handeye's pose file readers)")
    if isinstance(value, (str, bytes, Mapping)) or not (
            isinstance(value, (Sequence, np.ndarray, numbers.Number, np.generic)) or hasattr(value, "__array__")):
        raise InputError(f"{name} must be {expected}; could not convert it to floats (got a value of type "
                         f"{type(value).__name__!r})")
    try:
        return np.array(value, dtype=float, copy=True)
    except (TypeError, ValueError, OverflowError, RecursionError) as exc:
        raise InputError(f"{name} must be {expected}; could not convert it to floats "
                         f"({' '.join(str(exc).split())})") from None


def _float_copy(value: Any, name: str) -> np.ndarray:
    """`float_array` of a pose stack."""
    return float_array(value, name, POSE_STACK)


def same_length(stacks: dict[str, np.ndarray], min_pairs: int) -> int:
    """Check that all stacks have the same length m >= min_pairs; return m."""
    lengths = {name: len(s) for name, s in stacks.items()}
    if len(set(lengths.values())) != 1:
        raise InputError(f"data stacks must have the same length; got {lengths}")
    m = next(iter(lengths.values()))
    if m < min_pairs:
        raise DegenerateDataError(f"need at least {min_pairs} pose pairs, got {m}: record more poses")
    return m


def _indices(mask: np.ndarray, limit: int = 5) -> str:
    idx = np.flatnonzero(mask)
    shown = ", ".join(str(i) for i in idx[:limit])
    return shown + (f", ... ({len(idx)} in all)" if len(idx) > limit else "")


def pose_stacks(stacks: Mapping[str, Any], min_pairs: int) -> dict[str, np.ndarray]:
    """`pose_stack` of each named stack and `same_length`, as one vectorised pass over them all.

    Fast path: when every stack converts to a float (m, 4, 4) array of one shape, m >= min_pairs,
    and every pose passes pose_stack's checks with a margin (finite; last row within
    LAST_ROW_TOL; `orthonormality_error` below (1 - 1e-6) times its tolerance; det R > 0.5, i.e.
    +1 given the previous check), return the read-only copies pose_stack would (last row set
    exactly), in ~15 numpy calls on the stacked array instead of ~35 per stack (np.cross alone,
    pose_stack's determinant, costs more than all of this at m = 16). Anything else, including
    data at a check's boundary, goes through pose_stack and same_length themselves, which accept
    or raise their one-line errors naming the stack and the poses.
    """
    try:
        checked_one_by_one = any(_is_complex(v) or is_masked(v) or v is None
                                 or (isinstance(v, np.ndarray) and v.dtype.kind in "US") for v in stacks.values())
        arrays = [] if checked_one_by_one else [np.asarray(v, dtype=float) for v in stacks.values()]
    except (TypeError, ValueError, OverflowError):
        arrays = []  # pose_stack says what is wrong
    shape = arrays[0].shape if arrays else None
    if (arrays and len(shape) == 3 and shape[1:] == (4, 4) and shape[0] >= min_pairs
            and all(a.shape == shape for a in arrays)):
        T = np.concatenate(arrays)  # a new array: the caller's are not modified
        if _valid_poses(T):
            T[:, 3, :] = (0.0, 0.0, 0.0, 1.0)
            T.setflags(write=False)
            return {name: T[k * shape[0]:(k + 1) * shape[0]] for k, name in enumerate(stacks)}
    checked = {name: pose_stack(value, name) for name, value in stacks.items()}
    same_length(checked, min_pairs)
    return checked


def _valid_poses(T: np.ndarray) -> bool:
    """Whether every pose of T: (n, 4, 4) passes `pose_stack`'s checks with a margin (`pose_stacks`)."""
    with np.errstate(all="ignore"):
        # a sum is finite only if every entry is (an overflow merely sends the data to pose_stack)
        if not (np.isfinite(T.sum()) and np.abs(T[:, 3, :] - _LAST_ROW).max() <= LAST_ROW_TOL):
            return False
        if len(T) > 128:
            return _valid_rotations_by_entry(T)
        R = T[:, :3, :3]
        if not orthonormality_error(R).max() <= (1.0 - 1e-6) * ORTHONORMALITY_TOL:
            return False
        return bool(det(R).min() > 0.5)  # +-1 given the previous check


def _valid_rotations_by_entry(T: np.ndarray) -> bool:
    """`_valid_poses`' rotation checks on a large stack, entry by entry: each of the nine entries
    copied once into a contiguous row, then R^T R - I and det R (rule of Sarrus) by elementwise
    products of those rows. Strided access to a (n, 4, 4) stack reads a cache line per pose for
    every operation; this reads it once (2x faster than `orthonormality_error` and a gather at
    n = 2e5)."""
    a, b, c, d, e, f, g, h, i = np.ascontiguousarray(T[:, :3, :3].reshape(len(T), 9).T)
    err = np.abs(a * a + d * d + g * g - 1.0)
    for x in (b * b + e * e + h * h - 1.0, c * c + f * f + i * i - 1.0, a * b + d * e + g * h,
              a * c + d * f + g * i, b * c + e * f + h * i):
        np.maximum(err, np.abs(x), out=err)
    if not err.max() <= (1.0 - 1e-6) * ORTHONORMALITY_TOL:
        return False
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    return bool(det.min() > 0.5)  # +-1 given the previous check


#: the last row of a pose
_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])
_LAST_ROW.setflags(write=False)


#: data move beyond their noise when some motion's rotation (the smaller of the robot's and the
#: camera's angle) exceeds this many times the typical disagreement of the two angles, which is
#: the noise (the angle of a motion is the same for robot and camera: A = X B X^-1) ...
MOTION_NOISE_FACTOR = 3.0
#: ... or exceeds this angle (rad; 10 deg): a setup mistake (another Euler order, a shifted
#: pairing, unrelated files) also makes the angles disagree, by tens of degrees, but its robot
#: still turns by more than this and the plausibility checks name the mistake
MOTION_NOISE_MAX_ANGLE = np.deg2rad(10.0)


def check_motion_beyond_noise(angle_A: np.ndarray, angle_B: np.ndarray, what: str) -> None:
    """DegenerateDataError when the motions (rotation angles angle_A of the robot's, angle_B of the
    camera's, rad) do not rotate beyond the noise: no motion's smaller angle exceeds
    MOTION_NOISE_FACTOR times the median |angle_A - angle_B|, nor MOTION_NOISE_MAX_ANGLE.
    Repeated copies of one station with noise look like that (largest turn 0.03-0.07 deg against
    a disagreement of 0.16-0.26 deg, measured), and any answer from them is noise (53-176 deg
    off)."""
    angle_A, angle_B = np.asarray(angle_A, dtype=float), np.asarray(angle_B, dtype=float)
    if not len(angle_A):
        return
    noise = median(np.abs(angle_A - angle_B))
    largest = float(np.minimum(angle_A, angle_B).max())
    if noise > 0 and largest <= MOTION_NOISE_FACTOR * noise and largest < MOTION_NOISE_MAX_ANGLE:
        raise DegenerateDataError(
            f"the {what} do not move beyond their noise: the largest rotation between them is "
            f"{np.degrees(largest):.2g} deg, while robot and camera disagree by {np.degrees(noise):.2g} deg on a "
            "typical one (the same station recorded again and again?). Move the robot between stations: "
            "rotations of 30 deg or more about different axes")


#: two pose pairs (or a motion) agree when the robot's and the camera's rotation angles between
#: them differ by less than this (rad; 5 deg): clean pairs at ten times the accuracy study's noise
#: differ by 1-3 deg, a gross pair (a wrong detection, a mismatched pose) by tens of degrees
AGREEMENT_ANGLE = float(np.deg2rad(5.0))
#: `agreeing_share` looks at this many stations at most (evenly spread): enough to see a majority
AGREEMENT_STATIONS = 300


def agreeing_share(A: np.ndarray, B: np.ndarray) -> float:
    """The share of the stations A_i X = Y B_i (A, B: (m, 4, 4)) in the largest group that agree
    with each other (`agreeing_group`). At one half or below no majority of consistent stations
    exists, and no robust fit can tell the right answer from a wrong one. Measured (30 stations,
    random camera poses for the gross ones, 10 seeds): the clean share exactly, 0.7 / 0.6 / 0.5
    with 30 / 40 / 50% gross (0.40-0.43 with 60%); clean data 1.0 at up to ten times the accuracy
    study's noise, 0.62-1.0 at thirty times (8-50 stations)."""
    return float(agreeing_group(A, B).sum()) / min(len(A), AGREEMENT_STATIONS) if len(A) else 1.0


def agreeing_group(A: np.ndarray, B: np.ndarray,
                   angles: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """(m,) bool: the largest group of stations A_i X = Y B_i that agree with each other, among
    at most AGREEMENT_STATIONS evenly spread ones (`_agreeing_group`; beyond that many stations
    the others are False: the group is a sample, its share is `agreeing_share`). Stations i and j agree when
    their motion turns by the same angle for the robot and for the camera (A_j^-1 A_i =
    X B_j^-1 B_i X^-1), to AGREEMENT_ANGLE. It needs neither X nor Y, so gross pairs cannot bend
    it as they bend a fit: clean stations agree with the other clean ones, a gross one with
    almost none. `angles`: `agreement_angles(A, B)` when the caller has them."""
    k, angles_A, angles_B = agreement_angles(A, B) if angles is None else angles
    out = np.zeros(len(A), dtype=bool)
    if len(k) < 3:
        out[k] = True
        return out
    out[k[_agreeing_group(np.abs(angles_A - angles_B) < AGREEMENT_ANGLE)]] = True
    return out


def agreement_angles(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(k, angles_A, angles_B): the stations `agreeing_group` looks at (`_agreement_sample`) and
    the rotation angles (n, n) of R_j^T R_i between each two of them, of the robot's poses and of
    the camera's (from tr(R_j^T R_i); None for fewer than 3 stations). At up to
    AGREEMENT_STATIONS stations these are every station's, so they hold the angles from the first
    station and between consecutive ones too, which the validation of A X = Y B checks
    (`handeye.problems.axyb.data.station_angles`, the same numbers)."""
    k = _agreement_sample(len(A))
    if len(k) < 3:
        return k, None, None
    RA, RB = A[k, :3, :3], B[k, :3, :3]

    def angles(R: np.ndarray) -> np.ndarray:  # (n, n) angles of R_j^T R_i, from tr(R_j^T R_i)
        trace = einsum("jab,iab->ij", R, R)
        return np.arccos((0.5 * (trace - 1.0)).clip(-1.0, 1.0))

    return k, angles(RA), angles(RB)


def _agreement_sample(m: int) -> np.ndarray:
    if m <= AGREEMENT_STATIONS:  # every station (what the spread sample below gives: 20 us saved)
        return np.arange(m)
    return np.unique(np.linspace(0, m - 1, min(m, AGREEMENT_STATIONS)).astype(int))


def _agreeing_group(agree: np.ndarray) -> np.ndarray:
    """(n,) bool: a group of stations that agree with each other (`agree`: (n, n) bool): the
    station agreeing with the most, with those it agrees with, then, until nothing changes, only
    the members that agree with at least half the group (a gross station agrees by chance with a
    few clean ones, with ~5% of any group: it drops out)."""
    group = agree[int(np.argmax(agree.sum(axis=1)))].copy()
    for _ in range(10):
        # every station in the group (clean data): the whole matrix, without np.ix_'s ~8 us
        inside = (agree if group.all() else agree[np.ix_(group, group)]).sum(axis=1)
        keep = inside >= 0.5 * group.sum()
        if keep.all():
            break
        group[np.flatnonzero(group)[~keep]] = False
    return group


def agreeing_motions(angle_A: np.ndarray, angle_B: np.ndarray) -> np.ndarray:
    """(m,) bool: the motions (A_i X = X B_i) whose robot and camera rotation angles agree to
    AGREEMENT_ANGLE (`agreeing_group` for stations)."""
    return np.abs(np.asarray(angle_A) - np.asarray(angle_B)) < AGREEMENT_ANGLE
