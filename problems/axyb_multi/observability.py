"""What the observations of ``axyb-multi`` determine: the rule, its figures and its refusals.

**The rule.** Linearise A_i X_j = Y_k B_i at any solution, X_j <- exp([a_j]_x) X_j in the flange
frame, Y_k <- exp([b_k]_x) Y_k in the base frame: an observation's rotation rows ask
R_Ai a_j - b_k = 0, and with the rotations fixed its translation rows ask R_Ai u_j - w_k = 0 of
the translations' changes (u_j, w_k): the same coefficients. The data therefore determine the
unknowns exactly when the information matrix of those rows,

    G = sum_i E_i^T E_i,    E_i = [R_Ai at X_j, -I at Y_k]    (3 x 3(nX + nY)),

built from the robot's rotations and the graph alone (no unknown, no camera pose), is
nonsingular: G has diagonal blocks (observations of the unknown) I and off-diagonal blocks
-sum R_Ai^T over the observations of each (X, Y) pair; its null vectors are the changes no
observation sees. Two consequences, which the refusals and warnings below state:

- A null vector changes every unknown of its connected component of the observation graph (each
  observation carries its X's change to its Y's, |b_k| = |a_j|) and nothing outside it: a
  component is determined as a whole or not at all, and components never help each other (they
  are solved separately; `AXYBMultiData.components`). One observation ties X_j and Y_k completely
  (Y_k = A_i X_j B_i^-1), so an unknown joined by a single observation to a determined rest is
  determined, exactly but unchecked: nothing else sees its error (a warning, not a refusal).
- What determines a component is its cycles: two observations of one pair at stations i, l give
  the motion A_l^-1 A_i (the single-pair rule of ``axyb``), and longer cycles through other
  cameras and markers give products of the robot's poses. A component whose observations come
  from one station, or whose cycles all turn about one axis, is not determined (G singular; the
  robot rotating about one axis makes every component so): DegenerateDataError naming its
  unknowns and what to record.

**Figures** (`component_figures`, `unknown_figures`): per component its excitation, the smallest
eigenvalue of G normalised by the observations of each unknown (D^-1/2 G D^-1/2, in [0, 1]: 1 for
rotations spread in every direction, 0 undetermined; for one pair it is 1 - sigma_1(mean R_Ai),
so a set of robot rotations has the same figure in ``axyb-multi`` as one camera and one target);
per unknown its equivalent observations, 3 / tr((G^-1)_jj): as many independent observations of it
alone would determine it as well (for one pair of well spread stations about m; below 1 the unknown
rests on less than one observation's worth). Both are geometry only; the precision in rad and mm
is the covariance of the fit (refine's ``std``, the host's self-check).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from handeye.base.errors import DegenerateDataError
from handeye.geometry import so3_fast
from handeye.geometry.validation import check_motion_beyond_noise
from handeye.problems.planar import PLANAR_AXIS_SPREAD, main_axis

#: a component's excitation (module docstring) below which it is undetermined: structural null
#: vectors (one station, one motion's axis) give ~1e-16, any real determination far more
DEGENERATE_EXCITATION = 1e-10
#: ... below which it is weakly determined and a warning says so. Measured on one pair of 30
#: stations whose robot rotations turn about z tilted by up to +-d deg: 1.0e-4 at d = 1 (the
#: planar threshold of axyb, refused), 3.4e-4 at 2, 2.4e-3 at 5, 0.010 at 10; the simulator's
#: cells (`AXYBMulti.simulate`, both setups): 0.02 with 3 stations, 0.2-0.3 with 5, 0.4 with 30
WEAK_EXCITATION = 1e-3
#: an unknown with fewer equivalent observations than this is named in a warning (one observation
#: gives at most 1: it is determined, but nothing checks it)
FEW_EQUIVALENT = 1.5
#: at most this many names in one message (then "...")
LISTED = 8


def information(data: Any) -> np.ndarray:
    """G: (3n, 3n), n = nX + nY, of the module docstring (X's first, then Y's)."""
    nX, n = data.nX, data.nX + data.nY
    pairs, of = data.pair_index
    S = np.zeros((len(pairs), 3, 3))
    np.add.at(S, of, data.A[:, :3, :3])  # sum of R_A per observed pair
    count = np.bincount(data.x_index, minlength=nX).tolist() + np.bincount(data.y_index, minlength=data.nY).tolist()
    G = np.zeros((n, n, 3, 3))
    G[np.arange(n), np.arange(n)] = np.asarray(count, dtype=float)[:, None, None] * np.eye(3)
    G[pairs[:, 0], nX + pairs[:, 1]] = -np.swapaxes(S, 1, 2)
    G[nX + pairs[:, 1], pairs[:, 0]] = -S
    return G.transpose(0, 2, 1, 3).reshape(3 * n, 3 * n)


def _component_rows(data: Any, c: Any) -> np.ndarray:
    """The rows of G of a component's unknowns."""
    members = list(c.x) + [data.nX + k for k in c.y]
    return np.concatenate([np.arange(3 * u, 3 * u + 3) for u in members])


def component_figures(data: Any) -> list[dict[str, Any]]:
    """Per component (`AXYBMultiData.components`, largest first): its X's and Y's (names), its
    observations and stations, its excitation and its stations' axis spread (deg: the spread of
    the robot's rotation axes over its stations, `handeye.problems.planar.main_axis`)."""
    G = information(data)
    counts = np.r_[np.bincount(data.x_index, minlength=data.nX), np.bincount(data.y_index, minlength=data.nY)]
    out = []
    for c in data.components:
        rows = _component_rows(data, c)
        Gc = G[np.ix_(rows, rows)]
        scale = 1.0 / np.sqrt(np.repeat(counts[rows[::3] // 3], 3).astype(float))
        excitation = float(max(np.linalg.eigvalsh(Gc * scale[:, None] * scale[None, :])[0], 0.0)) if len(c.observations) else 0.0
        out.append({
            "X": [data.x_names[j] for j in c.x], "Y": [data.y_names[k] for k in c.y],
            "x": list(c.x), "y": list(c.y),
            "observations": int(len(c.observations)),
            "stations": int(len(np.unique(data.station_index[c.observations]))),
            "excitation": excitation,
            "axis_spread_deg": math.degrees(_axis_spread(data, c)),
        })
    return out


def unknown_figures(data: Any) -> dict[str, dict[str, Any]]:
    """Per unknown (keyed as the model's unknowns, X[j], Y[k]): its name, observations, stations,
    the unknowns it is seen with, and its equivalent observations (module docstring; 0 where its
    component is undetermined)."""
    G = information(data)
    station = data.station_index
    out: dict[str, dict[str, Any]] = {}
    for c in data.components:
        rows = _component_rows(data, c)
        Gc = G[np.ix_(rows, rows)]
        try:
            inv = np.linalg.inv(Gc) if _excitation_ok(Gc, data, rows) else None
        except np.linalg.LinAlgError:
            inv = None
        members = [("X", j) for j in c.x] + [("Y", k) for k in c.y]
        for u, (kind, idx) in enumerate(members):
            obs = data.observations_of(x=idx) if kind == "X" else data.observations_of(y=idx)
            partners = np.unique((data.y_index if kind == "X" else data.x_index)[obs])
            other = data.y_names if kind == "X" else data.x_names
            trace = float(np.trace(inv[3 * u:3 * u + 3, 3 * u:3 * u + 3])) if inv is not None else math.inf
            out[f"{kind}[{idx}]"] = {
                "name": (data.x_names if kind == "X" else data.y_names)[idx],
                "observations": int(len(obs)),
                "stations": int(len(np.unique(station[obs]))),
                "seen_with": [other[p] for p in partners.tolist()],
                "equivalent_observations": 3.0 / trace if trace > 0 and math.isfinite(trace) else 0.0,
            }
    return out


def _excitation_ok(Gc: np.ndarray, data: Any, rows: np.ndarray) -> bool:
    counts = np.diag(Gc)
    if not len(counts) or counts.min() <= 0:
        return False
    scale = 1.0 / np.sqrt(counts)
    return bool(np.linalg.eigvalsh(Gc * scale[:, None] * scale[None, :])[0] >= DEGENERATE_EXCITATION)


def _axis_spread(data: Any, c: Any) -> float:
    """The spread (rad) of the robot's rotation axes over the component's stations (consecutive
    motions between them, in the data's order): 0 for one station or one axis."""
    first = np.unique(data.station_index[c.observations], return_index=True)[1]
    A = data.A[np.sort(c.observations[first])]
    return main_axis(so3_fast.consecutive_logs(A))[1] if len(A) > 1 else 0.0


def _listing(names: list[str]) -> str:
    return ", ".join(names[:LISTED]) + (f" and {len(names) - LISTED} more" if len(names) > LISTED else "")


def check_determined(data: Any) -> list[dict[str, Any]]:
    """Refuse data that leave unknowns undetermined (module docstring), naming them and what to
    record (DegenerateDataError, one line); return `component_figures`. Per component, in order:
    one station; its robot poses rotating about one axis (axis spread below the planar threshold
    of ``axyb``, `handeye.problems.planar.PLANAR_AXIS_SPREAD`: the translations along the axis
    are then undetermined, and ``axyb-multi`` has no planar mode); an excitation below
    DEGENERATE_EXCITATION (its cycles turn about one axis); motions between observations of the
    same pair that do not turn beyond the noise (`check_motion_beyond_noise`)."""
    figures = component_figures(data)
    many = len(figures) > 1
    for c, f in zip(data.components, figures):
        names = f["X"] + f["Y"]
        group = _listing(names) + (" (a group of their own: no observation ties them to the other X's and Y's)"
                                   if many else "")
        they = "them" if len(names) > 1 else "it"
        if f["stations"] < 2:
            obs = _listing([str(i) for i in c.observations.tolist()])
            raise DegenerateDataError(
                f"{group} {'are' if len(names) > 1 else 'is'} seen at one station only (observation"
                f"{'s' if f['observations'] > 1 else ''} {obs}), which cannot determine {they}: record {they} from "
                "at least three stations that rotate the robot about different axes, or at a station where one of "
                f"{'their' if len(names) > 1 else 'its'} cameras also sees a marker of the others")
        if math.radians(f["axis_spread_deg"]) < PLANAR_AXIS_SPREAD:
            raise DegenerateDataError(
                f"the robot poses of {group} rotate about one axis (axis spread {f['axis_spread_deg']:.2g} deg), so "
                f"the data cannot determine {they} (the translations along that axis; axyb-multi has no planar mode): "
                "record poses that rotate about at least two different axes")
        if f["excitation"] < DEGENERATE_EXCITATION:
            raise DegenerateDataError(
                f"the robot motions that tie {group} together rotate about one axis (excitation "
                f"{f['excitation']:.1e} < {DEGENERATE_EXCITATION:g}: the same camera sees the same marker at two "
                f"stations only, or at stations related by turns about one axis), so the data cannot determine {they}: "
                "record stations that rotate the robot about different axes, each camera seeing the same markers "
                "at several of them")
        phi_A, _, phi_B, _ = _pair_motions_of(data, c)
        check_motion_beyond_noise(np.linalg.norm(phi_A, axis=1), np.linalg.norm(phi_B, axis=1),
                                  f"stations of {group}" if many else "stations")
    return figures


def _pair_motions_of(data: Any, c: Any) -> tuple[np.ndarray, ...]:
    from handeye.problems.axyb_multi.geometry import pair_motions

    if len(data.components) == 1:
        return pair_motions(data)
    return pair_motions(data.subset(c.observations))


def warnings(data: Any, components: list[dict[str, Any]] | None = None,
             unknowns: dict[str, dict[str, Any]] | None = None) -> list[str]:
    """What the user should know about determined data: separate components (solved separately),
    weakly determined components, unknowns that rest on one observation or few."""
    components = component_figures(data) if components is None else components
    unknowns = unknown_figures(data) if unknowns is None else unknowns
    out = []
    if len(components) > 1:
        groups = "; ".join(f"{_listing(f['X'])} with {_listing(f['Y'])} ({f['observations']} observations)"
                           for f in components[:LISTED])
        out.append(f"the observations form {len(components)} separate groups that share no X or Y ({groups}"
                   f"{' ...' if len(components) > LISTED else ''}): nothing ties one group's poses to another's, "
                   "so each group is solved separately from its own observations")
    for f in components:
        if DEGENERATE_EXCITATION <= f["excitation"] < WEAK_EXCITATION:
            out.append(f"the robot motions that determine {_listing(f['X'] + f['Y'])} turn about nearly one axis "
                       f"(excitation {f['excitation']:.1e} < {WEAK_EXCITATION:g}): their poses are weakly determined; "
                       "record stations that rotate the robot about different axes, seen by the same cameras")
    single = [u["name"] for u in unknowns.values() if u["observations"] == 1]
    if single:
        out.append(f"{_listing(single)} {'rests' if len(single) == 1 else 'rest'} on a single observation: "
                   f"{'it is' if len(single) == 1 else 'they are'} determined through the others, but nothing checks "
                   f"{'it' if len(single) == 1 else 'them'} (a gross error there goes unseen): record "
                   f"{'it' if len(single) == 1 else 'them'} from more stations or cameras")
    few = [f"{u['name']} ({u['equivalent_observations']:.2g})" for u in unknowns.values()
           if u["observations"] > 1 and 0 < u["equivalent_observations"] < FEW_EQUIVALENT]
    if few:
        out.append(f"{_listing(few)} {'is' if len(few) == 1 else 'are'} determined by less than "
                   f"{FEW_EQUIVALENT:g} observations' worth (equivalent observations in brackets): record "
                   f"{'it' if len(few) == 1 else 'them'} from more stations that rotate the robot about different axes")
    return out
