"""The self-check's test for systematic robot errors: residuals that follow the arm's configuration.

On a real cell the robot's own systematic errors (its kinematics: DH parameters off by tenths of
a millimetre and of a degree) often dominate, and the covariance of the answer cannot see them:
it takes every station's residual as independent noise. Such an error is a smooth function of
the arm's joints, hence of where the flange is; noise is not. So the residuals at the best fit
(`handeye.checks.self_check`'s check 2) are regressed on smooth functions of the flange's position at
each station, and an F test asks whether that explains more than noise would:

    e_i (6 numbers: rotation and translation residual of station i, whitened), Z_i = (p_i - mean p) / RMS
    H1: e_i = B Z_i + noise, B a 6x3 matrix (18 coefficients), against H0: e_i = noise

The test is on the mean of the residuals, not on their spread: noise whose size depends on the
station (a camera's rotation noise moved by its distance to the board, a robot's by the lever
arm) has zero mean everywhere and does not make it fire. Three details make it exact at that:

- the 6 components of a station are decorrelated first by their pooled 6x6 covariance (a
  camera's rotation noise moves its translation too: with per-group weights only, the F test
  fired at p < 1e-3 on up to 4% of simulated data sets with such noise; decorrelated, on none);
- the regressors are projected off the columns of the fit's Jacobian (what X and Y absorb), and
  the degrees of freedom counted after that projection (the augmented-model F test);
- stations far off the others (gross pairs, check 3) are left out.

Why positions and not orientations too: 72 regressors (position and the rotation matrix) leave
30 stations too few degrees of freedom, and more regressors spread the same signal over more of
them. Why this statistic: the nearest-neighbour autocorrelation of the residuals (stations close
in flange pose, against a permutation null) and a held-out half of the workspace (a Chow test of
X and Y fitted on each half) were measured beside it on simulated arms with DH errors and
detect less (65% against 25% and 35% at 30 stations and half the simulator's DH errors), and
fired on lever-arm noise (docs/reliability.md, "Systematic robot errors"; bench/systematic.py).

What the data show of such errors also widens the answer's 1-sigma: the spread of the best fit
when groups of consecutive stations are left out (`station_spread`, a linearised jackknife),
where larger than the covariance of independent noise, per unknown (the host applies it:
`handeye.framework.solution.with_spread`). A part every station shares (e.g. an error of the
last joint, which moves X alike at every station) no data of the arm show; the warning says so.

The warning fires at p < `P_WARN` and needs `MIN_STATIONS` stations. A problem takes part through
the optional `handeye.framework.problem.Problem.configurations` (the flange poses of the rows of its
`check_model`'s model).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.linalg.lapack import dgeqp3, dorgqr
from scipy.special import fdtrc

from handeye.geometry.linalg import eigh

#: the warning's significance level. Measured (bench/systematic.py): no false alarm in 900 tests
#: of simulated perfect arms (camera, robot and camera, lever-arm and heavy noise, 15-60
#: stations), nor on the 296 KinHEC small-tier sequences without robot or model errors (at 0.01:
#: 4 of them)
P_WARN = 1e-3
#: fewest stations (rows) for the test: 6m residuals against 12 unknowns and 18 coefficients
MIN_STATIONS = 12
#: columns whose pivoted-QR diagonal is below this share of the largest are dropped (rank)
RANK_TOL = 1e-8
#: residuals whose RMS is below this (rotation rad; translation as a share of the data's lever
#: arm) are rounding, not noise: noise-free data leave ~1e-13, whose structure follows the
#: configuration as anything computed from it does (the test fired at p = 2e-4 on one of five
#: noise-free simulated cells), so there is nothing to test
ROUNDING = 1e-9
#: the stations' spread (`station_spread`) deletes one of at most this many groups of consecutive
#: stations at a time
SPREAD_GROUPS = 10
#: the test runs on at most this many stations, spread evenly over the data's order (the rest
#: left out: the residuals of the full fit projected off the subset's Jacobian are exactly those
#: of a fit to the subset, so the F test stays exact). Measured: 2.0 s of a 2.7 s solve at 10^5
#: stations before; 2000 stations detect what the test detects at 30
MAX_STATIONS = 2000


def position_features(poses: np.ndarray) -> np.ndarray | None:
    """The regressors Z: (m, 3), the flange positions centred and divided by their RMS distance
    from the centre; None when they do not spread (every station at one point)."""
    p = np.asarray(poses, dtype=float)[:, :3, 3]
    c = p - p.sum(axis=0) / len(p)  # np.mean's arithmetic, without its wrapper (twice)
    rms = math.sqrt(float((c * c).sum(axis=1).sum()) / len(c))
    return c / rms if rms > 0 else None


def configuration_test(ew: np.ndarray, J: np.ndarray, Z: np.ndarray,
                       station: np.ndarray | None = None) -> dict[str, float] | None:
    """The F test of the module docstring: whitened residuals ew: (m, 6) at a least-squares fit,
    whitened Jacobians J: (m, 6, n) there, regressors Z: (m, q). Returns {"F", "p_value",
    "dof_num", "dof_den", "explained" (the share of the residuals' sum of squares the
    regressors explain)}, or None when too few degrees of freedom remain.

    `station`: (m,) the station of each row, where several rows share one (a cell's cameras and
    markers seen at one station share its robot reading, and so its robot noise: row by row the
    test would count that noise as many times as the station has rows, and fired on 2.5% of
    simulated cells). Then the projected residuals and regressors are summed per station, each
    sum divided by the root of its rows (orthonormal sums: iid row noise stays iid), and the test
    runs on the stations, its denominator's degrees of freedom 6S - k less what the fit's
    projection took from the sums (the squared norm of the summed projector's columns)."""
    m = len(ew)
    w, V = eigh(ew.T @ ew / m)  # LAPACK directly (`handeye.geometry.linalg.eigh`: numpy's numbers)
    if not w[-1] > 0:
        return None
    w = np.maximum(w, 1e-12 * w[-1])
    T = (V / np.sqrt(w)).T  # S^(-1/2): decorrelates the six components
    y = (ew @ T.T).ravel()
    Q = _column_basis((T @ J).reshape(6 * m, -1))
    q = Z.shape[1]
    # the regressors of row (i, a), coefficient (c, k): T[a, c] Z[i, k] (B Z_i, then decorrelated)
    D = (T[None, :, :, None] * Z[:, None, None, :]).reshape(6 * m, 6 * q)
    D -= Q @ (Q.T @ D)
    y = y - Q @ (Q.T @ y)
    removed = float(Q.shape[1])
    if station is not None:
        sums = _station_sums(station)
        y, D = sums(y.reshape(m, 6)).ravel(), sums(D.reshape(m, 6, -1)).reshape(-1, D.shape[1])
        removed = float(np.sum(sums(Q.reshape(m, 6, -1)) ** 2))
        m = int(np.max(station)) + 1
    U2 = _column_basis(D)
    k = U2.shape[1]
    dof = int(round(6 * m - removed)) - k
    if k == 0 or dof < 2 * k:
        return None
    rss0 = float(y @ y)
    explained = float(((U2.T @ y) ** 2).sum())
    rss1 = max(rss0 - explained, 1e-300)
    F = (explained / k) / (rss1 / dof)
    return {"F": F, "p_value": float(fdtrc(k, dof, F)), "dof_num": k, "dof_den": dof,
            "explained": explained / rss0 if rss0 > 0 else 0.0}


def _column_basis(M: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the column space of M (rows, n): the leading columns of its
    pivoted QR whose diagonal exceeds RANK_TOL of the first (rank-revealing; a third of the time
    of the SVD on these small matrices, which the self-check runs on every answer)."""
    n = M.shape[1]
    if n == 0:
        return M[:, :0]
    qr, _, tau, _, _ = dgeqp3(M)  # LAPACK directly: scipy.linalg.qr's checks double the time here
    d = np.abs(np.diag(qr))
    if not d[0] > 0:
        return M[:, :0]
    Q, _, _ = dorgqr(qr[:, :n], tau)
    return Q[:, :int(np.count_nonzero(d > RANK_TOL * d[0]))]


def _station_sums(station: np.ndarray):
    """x: (m, ...) -> (S, ...): the rows of each station summed, divided by the root of their count."""
    counts = np.bincount(station)
    scale = 1.0 / np.sqrt(counts)

    def sums(x: np.ndarray) -> np.ndarray:
        out = np.zeros((len(counts),) + x.shape[1:])
        np.add.at(out, station, x)
        return out * scale.reshape((-1,) + (1,) * (x.ndim - 1))

    return sums


#: up to this many poses `_stations` first asks whether all are distinct, by their bits (one set
#: of 16 byte strings: 3 us, where the keys and np.unique take 20 us); any repeated: the keys
DISTINCT_CHECK = 256
#: the fixed random projection of a pose's 12 entries that `_stations` keys stations by
_KEY_WEIGHTS = np.random.default_rng(0).uniform(0.5, 1.5, 12)


def _stations(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the first row of each station, the station of each row) for poses (m, 4, 4): rows with
    the very same pose are one station. Unique over one number per pose, a fixed random
    projection of its 12 entries (equal poses give equal bits; others collide with probability
    ~0): 30x faster than unique rows at 10^5 poses. Up to DISTINCT_CHECK poses, all distinct
    (by their bits): every row its own station, in the rows' order."""
    weights = _KEY_WEIGHTS
    entries = poses[:, :3, :].reshape(len(poses), 12)
    if len(poses) <= DISTINCT_CHECK:  # every pose distinct (the usual data): each row its own station
        distinct = {row.tobytes() for row in entries + 0.0}  # + 0.0: -0.0 and 0.0 are one value
        if len(distinct) == len(poses):
            return np.arange(len(poses)), np.arange(len(poses))
    key = np.zeros(len(poses))
    for k in range(12):  # elementwise in a fixed order, not BLAS: equal rows must give equal bits
        key += entries[:, k] * weights[k]
    _, first, station = np.unique(key, return_index=True, return_inverse=True)
    return first, station.ravel()


def assess_configuration(configurations: np.ndarray | None, model: Any, res: Any, flagged: np.ndarray,
                         warnings: list[str], figures: dict[str, Any], covered: bool = False,
                         cov: np.ndarray | None = None, stated: bool = True) -> None:
    """The check for `handeye.checks.self_check`: the residuals of its best fit `res` (the engine's
    result for `model`, `cov` its covariance) regressed on the flange positions `configurations`
    ((m, 4, 4), one per row of the model; None: the problem gives none), the rows `flagged` far
    off left out; a warning beyond P_WARN, the figures in ``figures["systematic"]``. `covered`:
    the answer's 1-sigma was estimated from the spread over its stations (a jackknife), which
    takes in errors shared by a station's measurements; the warning then says so instead of
    calling it too small. Otherwise the spread of the fit over groups of its stations
    (`station_spread`) gives per unknown how much wider its 1-sigma must be, whether or not the
    test fires (``figures["systematic"]["spread"]``, which the host applies to the answer's stated
    1-sigma: `handeye.framework.solution.with_spread`). `stated`: the answer states a 1-sigma
    (else the warning says that none carries the errors)."""
    if configurations is None:
        return
    poses = np.asarray(configurations, dtype=float)
    if poses.shape != (model.m, 4, 4):
        return
    e = np.asarray(res.e, dtype=float)
    rot, trans = e[:, :3], e[:, 3:]  # RMS of each group (np.mean's arithmetic, fewer calls)
    if (math.sqrt(float((rot * rot).sum()) / max(rot.size, 1)) < ROUNDING
            and math.sqrt(float((trans * trans).sum()) / max(trans.size, 1)) < ROUNDING * max(float(model.scale), 1e-300)):
        return
    keep = ~np.asarray(flagged, dtype=bool)
    # rows that share a robot reading (the same pose) are one station (`configuration_test`)
    first, station = _stations(poses[keep])
    stations = int(station.max()) + 1 if len(station) else 0
    if stations < MIN_STATIONS:
        return
    if stations > MAX_STATIONS:  # stations evenly spread in the data's order, all rows of each
        order = np.argsort(first)  # station numbers in the order they first appear
        chosen = np.zeros(stations, dtype=bool)
        chosen[order[np.linspace(0, stations - 1, MAX_STATIONS).round().astype(int)]] = True
        rows = np.flatnonzero(keep)[chosen[station]]
        keep = np.zeros_like(keep)
        keep[rows] = True
        _, station = np.unique(station[chosen[station]], return_inverse=True)
        station = station.ravel()
    Z = position_features(poses[keep])
    if Z is None:
        return
    ew = res.W.residual(res.e)[keep]
    rows = getattr(model, "rows", None)  # the Jacobian of the rows tested only, where the model can
    if keep.all():  # every row: the model's own Jacobian (the same numbers; the scale check's, where kept)
        J = res.W.jacobian(model.jacobian(res.poses, res.e))
    else:
        J = res.W.jacobian(rows(np.flatnonzero(keep)).jacobian(res.poses, res.e[keep]) if rows is not None
                           else model.jacobian(res.poses, res.e)[keep])
    out = configuration_test(ew, J, Z, station if int(station.max()) + 1 < len(station) else None)
    if out is None:
        return
    figures["systematic"] = {**out, "stations": stations, "tested_stations": int(station.max()) + 1}
    spread = None if covered or cov is None else station_spread(J, ew, station, cov, res.P, model.unknowns)
    if spread is not None:
        figures["systematic"]["spread"] = spread
    if out["p_value"] < P_WARN:
        widest = max((max(f.values()) for f in (spread or {}).values()), default=1.0)
        how = ("estimated from the spread over the stations, not from the noise" if covered else
               f"widened up to {widest:.2g}x to the spread of the answer over groups of the stations" if widest > 1.0
               else "the spread of the answer over groups of the stations is no wider")
        carried = ("this solver's answer states no uncertainty to carry them (solver 'auto' states one that takes "
                   "them in as far as they differ between stations)" if not stated else
                   f"the stated 1-sigma takes in only as far as they differ between stations ({how}): what every "
                   "station shares moves the answer further, by several of its sigmas on simulated arms"
                   if covered or spread is not None else
                   "the stated uncertainty of the answer leaves out: it may be off by several of its sigmas")
        warnings.append(
            f"self-check: the residuals follow the arm's configuration: the flange's position explains "
            f"{out['explained']:.0%} of them (F test, p = {out['p_value']:.1g}), which noise does not do. "
            "That is the mark of systematic robot errors (its kinematics: DH parameters), which " + carried
            + " (a camera scale that drifts, or a clock offset between the streams, leave the same mark). "
            "To remove them rather than carry them, record the joint angles and "
            "calibrate the kinematics with the hand-eye (problem 'axyb-kinematic', docs/kinematic.md), or spread "
            "the stations over the whole workspace the cell uses")


def station_spread(J: np.ndarray, ew: np.ndarray, station: np.ndarray, cov: np.ndarray, P: np.ndarray | None,
                   unknowns: tuple[str, ...]) -> dict[str, dict[str, float]] | None:
    """Per unknown, by how much the spread of the fit over groups of its stations
    (`group_jackknife`) exceeds its covariance `cov` (6k, 6k): {name: {"rotation": f,
    "translation": f}}, f = the root of the ratio of the traces of the 3x3 blocks, at least 1;
    None where leaving a group out leaves the unknowns undetermined.

    Systematic robot errors make neighbouring stations' residuals alike, which the covariance of
    independent noise does not see; the spread of the answer when a group of stations is left
    out does, as far as the error differs between stations (a part every station shares moves
    the answer alike whichever are left out: no data of the arm show it). The larger of the two
    is stated, as for intrinsics calibrated from images (`handeye.vision.intrinsics_check`).
    Measured: on simulated cells with independent noise the 1-sigma grows 9-17% on average and
    the errors' z RMS goes from 0.93-1.09 to 0.88-1.03 (15-60 pairs); on the ETH streams the
    split-half z RMS went from 1.2-2.3 to 0.7-1.6 (docs/reliability.md)."""
    spread = group_jackknife(J, ew, station, P)
    if spread is None:
        return None
    out = {}
    for j, name in enumerate(unknowns):
        factors = {}
        for kind, at in (("rotation", 6 * j), ("translation", 6 * j + 3)):
            model = float(np.trace(cov[at:at + 3, at:at + 3]))
            wider = float(np.trace(spread[at:at + 3, at:at + 3])) / model if model > 0 else 1.0
            factors[kind] = math.sqrt(max(1.0, wider))
        out[name] = factors
    return out


def group_jackknife(J: np.ndarray, ew: np.ndarray, station: np.ndarray, P: np.ndarray | None = None
                    ) -> np.ndarray | None:
    """The delete-one-group jackknife covariance (6k, 6k) of a least-squares fit over at most
    `SPREAD_GROUPS` groups of consecutive stations (in the data's order: a stream's neighbours in
    time leave together), linearised at the fit as the corner fit's station jackknife is
    (`handeye.plugins.reprojection.corners.station_jackknife`): without group g the fit moves by
    d_g = (H - H_g)^-1 J_g^T e_g, for the whitened Jacobian J (m, 6, 6k) and residuals `ew` (m, 6)
    of the rows, `station` (m,) the station of each, H = J^T J; C = (G - 1) / G sum_g (d_g -
    mean)(d_g - mean)^T. Exact for a linear model. `P`: the basis (6k, n) of the free parameters
    (fixed translation components), or None. None where a group's removal leaves H - H_g
    singular."""
    J = np.asarray(J, dtype=float)
    if P is not None:
        J = J @ P
    stations = int(station.max()) + 1
    groups = min(stations, SPREAD_GROUPS)
    order = np.empty(stations, dtype=np.intp)
    _, first = np.unique(station, return_index=True)
    order[np.argsort(first)] = np.arange(stations)  # stations numbered in the order they first appear
    group = order[station] * groups // stations
    Jf = J.reshape(len(J) * 6, -1)
    H = Jf.T @ Jf
    moves = []
    for g in range(groups):
        rows = group == g
        Jg = J[rows].reshape(-1, J.shape[2])
        try:
            moves.append(np.linalg.solve(H - Jg.T @ Jg, Jg.T @ ew[rows].ravel()))
        except np.linalg.LinAlgError:
            return None
    D = np.array(moves) if P is None else np.array(moves) @ P.T
    if not np.all(np.isfinite(D)):
        return None
    D -= D.mean(axis=0)
    return (groups - 1) / groups * (D.T @ D)
