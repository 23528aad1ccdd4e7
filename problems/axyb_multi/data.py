"""The data of ``axyb-multi``: observations A_i X_{x_i} = Y_{y_i} B_i of a cell with several
cameras and several targets, validated once (`AXYBMultiData`).

Each observation i is one station's robot pose A_i = T_base_flange and one camera's pose of one
target B_i, with the indices of the X and the Y it ties: for fixed cameras watching markers on the
flange, X_j = T_flange_marker_j and Y_k = T_base_cam_k, B_i = T_cam_marker; for cameras on the
wrist watching boards in the workcell, X_j = T_flange_cam_j and Y_k = T_base_board_k, B_i =
T_board_cam (docs/conventions.md, "Several cameras and targets"). The observations form a
bipartite graph of X's and Y's (an edge per observation); a connected component of it is a cell
of its own, solved separately: nothing ties its unknowns to another component's.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.estimation.kronecker import translation_rms, validated_stacks

#: the data stacks and the index fields
STACKS = ("A", "B")
INDEXES = ("x_index", "y_index")
#: the facts the data may carry besides them: names of the X's and the Y's
NAME_FIELDS = ("x_names", "y_names")


@dataclasses.dataclass(frozen=True)
class Component:
    """A connected component of the observation graph: the X's and Y's it holds (indices into the
    stacks, ascending) and its observations (indices into A, B)."""

    x: tuple[int, ...]
    y: tuple[int, ...]
    observations: np.ndarray


@dataclasses.dataclass(frozen=True)
class AXYBMultiData:
    """Validated observations: A, B (m, 4, 4) read-only float64; x_index, y_index (m,) read-only
    int64 numbering the X's 0..nX-1 and the Y's 0..nY-1, each used at least once; the names of
    the X's and Y's (default ``X0``, ``X1``, ... and ``Y0``, ...)."""

    A: np.ndarray
    B: np.ndarray
    x_index: np.ndarray
    y_index: np.ndarray
    x_names: tuple[str, ...]
    y_names: tuple[str, ...]
    #: some cameras' translations are known only up to scale, each camera's own
    #: (`handeye.estimation.camera_scales`): those of the X's `scaled_x` and the Y's `scaled_y` (indices),
    #: the data's ``camera_scale`` list of names (docs/camera-scale.md, "Several cameras")
    camera_scale_unknown: bool = False
    scaled_x: tuple[int, ...] = ()
    scaled_y: tuple[int, ...] = ()
    #: the stacks the indices belong to (set by `__post_init__`; not compared, not shown), so that
    #: ``dataclasses.replace(data, A=data.A[keep], B=data.B[keep])`` (how a solver leaves pairs
    #: out, e.g. ``auto``'s outlier step) keeps the indices aligned: see `__post_init__`
    _stacks: tuple[np.ndarray, np.ndarray] | None = dataclasses.field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        """Keep x_index, y_index aligned with A, B. When A, B were replaced by a subset of their
        observations in order (``dataclasses.replace(data, A=A[keep], B=B[keep])``, which leaves the
        indices as they were), the observations kept are found in the stacks the indices belong to
        and the indices subset alike; the names stay (an X or Y left without observations is then
        undetermined, and a fit of it singular). Anything else that misaligns them is an error."""
        m = len(self.A)
        if len(self.B) != m:
            raise InputError(f"A and B must hold one pose per observation, got {len(self.A)} and {len(self.B)}")
        if len(self.x_index) != m or len(self.y_index) != m:
            aligned = (self._stacks is not None and len(self.x_index) == len(self.y_index) == len(self._stacks[0]))
            keep = _kept_rows(self._stacks, self.A, self.B) if aligned else None
            if keep is None:
                raise InputError(f"x_index and y_index must hold one index per observation ({m}), got "
                                 f"{len(self.x_index)} and {len(self.y_index)}; take a subset with "
                                 "AXYBMultiData.subset(observations)")
            object.__setattr__(self, "x_index", _frozen(self.x_index[keep]))
            object.__setattr__(self, "y_index", _frozen(self.y_index[keep]))
        object.__setattr__(self, "_stacks", (self.A, self.B))
        if self.camera_scale_unknown and not (self.scaled_x or self.scaled_y):
            raise InputError("camera_scale_unknown needs the cameras whose scale is unknown: give camera_scale=[their "
                             "names] (a fixed camera is a Y, a wrist camera an X)")

    @functools.cached_property
    def camera_scale_groups(self) -> tuple[np.ndarray, tuple[str, ...]] | None:
        """(groups (m,), names): the camera whose unknown scale each observation's t_B carries
        (0, 1, ... in the order of `names`: the scaled X's, then the scaled Y's; -1: a metric
        camera's observation), or None when every camera is metric."""
        if not self.camera_scale_unknown:
            return None
        groups = np.full(self.m, -1, dtype=np.int64)
        for c, j in enumerate(self.scaled_x):
            groups[self.x_index == j] = c
        for c, k in enumerate(self.scaled_y, start=len(self.scaled_x)):
            groups[self.y_index == k] = c
        names = tuple(self.x_names[j] for j in self.scaled_x) + tuple(self.y_names[k] for k in self.scaled_y)
        return _frozen(groups), names

    def scaled_cameras_model(self, model: Any) -> Any:
        """`model` with each unknown camera scale profiled out (`handeye.estimation.camera_scales`), for
        `handeye.estimation.camera_scale.model_for`."""
        from handeye.estimation.camera_scales import ScaledCamerasModel

        return ScaledCamerasModel(model, *self.camera_scale_groups)

    @property
    def m(self) -> int:
        return len(self.A)

    @property
    def nX(self) -> int:  # noqa: N802 - the paper's names
        return len(self.x_names)

    @property
    def nY(self) -> int:  # noqa: N802
        return len(self.y_names)

    @functools.cached_property
    def translation_scale(self) -> float:
        """RMS norm of all translations of A and B: the data's length unit, for normalisation."""
        return translation_rms(self.A, self.B)

    @functools.cached_property
    def components(self) -> tuple[Component, ...]:
        """The connected components of the observation graph, largest first (ties: lowest X)."""
        return components(self.x_index, self.y_index, self.nX, self.nY)

    @functools.cached_property
    def pair_index(self) -> tuple[np.ndarray, np.ndarray]:
        """The distinct (X, Y) pairs observed, (P, 2) int64 in ascending order, and the pair of each
        observation, (m,) indices into them."""
        pairs, of = np.unique(np.stack([self.x_index, self.y_index], axis=1), axis=0, return_inverse=True)
        return _frozen(pairs.astype(np.int64)), _frozen(np.asarray(of, dtype=np.int64).reshape(-1))

    @functools.cached_property
    def station_index(self) -> np.ndarray:
        """(m,) the station of each observation: observations with the same robot pose A (equal to
        the last bit, as a station's pose copied to each of its observations is) share one,
        numbered 0, 1, ... in the order they first appear."""
        _, first, of = np.unique(self.A.reshape(self.m, 16), axis=0, return_index=True, return_inverse=True)
        rank = np.empty(len(first), dtype=np.int64)
        rank[np.argsort(first)] = np.arange(len(first))
        return _frozen(rank[np.asarray(of).reshape(-1)])

    @property
    def station_count(self) -> int:
        """The number of distinct robot poses (`station_index`). (Not ``stations``: that attribute
        marks data of motions rebuilt from stations, which refine and auto treat apart.)"""
        return int(self.station_index.max()) + 1 if self.m else 0

    @property
    def names(self) -> tuple[str, ...]:
        """The names of the X's then the Y's, in the order of the model's unknowns
        (`handeye.framework.problem_engine.flat_names`: X[0], ..., Y[0], ...)."""
        return self.x_names + self.y_names

    @functools.cached_property
    def observability(self) -> tuple[list[dict[str, Any]], dict[str, dict[str, Any]]]:
        """What the observations determine (`observability.component_figures` and
        `observability.unknown_figures`), computed once."""
        from handeye.problems.axyb_multi import observability

        return observability.component_figures(self), observability.unknown_figures(self)

    @functools.cached_property
    def pose_model(self) -> Any:
        """The engine's model of these data (`geometry.AXYBMultiModel`), built once: refine, its
        outlier step and the host's self-check all use it (read-only)."""
        from handeye.problems.axyb_multi.geometry import AXYBMultiModel

        return AXYBMultiModel(self)

    @functools.cached_property
    def item_groups(self) -> dict[str, np.ndarray]:
        """The observations of each X and each Y by its name: the groups in which `auto`'s
        outlier step looks for errors that strike one camera or marker as a whole (a wrong
        unit or label), not observations at random."""
        return {**{name: self.observations_of(x=j) for j, name in enumerate(self.x_names)},
                **{name: self.observations_of(y=k) for k, name in enumerate(self.y_names)}}

    @functools.cached_property
    def pair_groups(self) -> dict[str, np.ndarray]:
        """The observations of each (X, Y) pair, by the pair's name ("marker3 with cam5"): where
        `auto`'s outlier step leaves out every observation of one pair, it names the pair (a tag
        badly printed or seen edge-on by that camera) instead of listing observations."""
        pairs, of = self.pair_index
        return {f"{self.x_names[x]} with {self.y_names[y]}": np.flatnonzero(of == p) for p, (x, y) in enumerate(pairs)}

    def component_names(self, c: Component) -> str:
        """A component's unknowns for messages: "X 'marker0', X 'marker1' and Y 'cam0'"."""
        listed = lambda kind, names, ids: ", ".join(f"{kind} {names[k]!r}" for k in ids)  # noqa: E731
        return f"{listed('X', self.x_names, c.x)} and {listed('Y', self.y_names, c.y)}"

    def item_label(self, i: int) -> str:
        """Observation i in the user's words, for messages: "marker3 with cam5 at station 4"
        (stations numbered from 0 in the order they first appear, `station_index`)."""
        return (f"{self.x_names[self.x_index[i]]} with {self.y_names[self.y_index[i]]} at station "
                f"{int(self.station_index[i])}")

    def observations_of(self, x: int | None = None, y: int | None = None) -> np.ndarray:
        """Indices of the observations of X `x` and/or Y `y`."""
        keep = np.ones(self.m, dtype=bool)
        if x is not None:
            keep &= self.x_index == x
        if y is not None:
            keep &= self.y_index == y
        return np.flatnonzero(keep)

    def subset(self, observations: np.ndarray) -> AXYBMultiData:
        """The data of these observations only, the X's and Y's they use renumbered in order
        (their names kept)."""
        observations = np.asarray(observations)
        xs, x_new = np.unique(self.x_index[observations], return_inverse=True)
        ys, y_new = np.unique(self.y_index[observations], return_inverse=True)
        scaled_x = tuple(int(np.searchsorted(xs, j)) for j in self.scaled_x if j in xs)
        scaled_y = tuple(int(np.searchsorted(ys, k)) for k in self.scaled_y if k in ys)
        return AXYBMultiData(_frozen(self.A[observations]), _frozen(self.B[observations]),
                             _frozen(x_new.astype(np.int64)), _frozen(y_new.astype(np.int64)),
                             tuple(self.x_names[k] for k in xs), tuple(self.y_names[k] for k in ys),
                             self.camera_scale_unknown and bool(scaled_x or scaled_y), scaled_x, scaled_y)

    def with_scales_unknown(self, names: Sequence[str]) -> AXYBMultiData:
        """The same data with the scales of the X's and Y's called `names` unknown, each its own
        (as ``camera_scale=[names]`` gives them); no names: as they are."""
        if not names:
            return self
        return dataclasses.replace(self, camera_scale_unknown=True,
                                   scaled_x=tuple(j for j, n in enumerate(self.x_names) if n in names),
                                   scaled_y=tuple(k for k, n in enumerate(self.y_names) if n in names))

    def scaled(self, s: float) -> AXYBMultiData:
        """The same data with every translation divided by s."""
        A, B = np.array(self.A), np.array(self.B)
        A[:, :3, 3] /= s
        B[:, :3, 3] /= s
        return dataclasses.replace(self, A=_frozen(A), B=_frozen(B))


def validated(problem: str, data: Mapping[str, Any], min_pairs: int) -> AXYBMultiData:
    """The data object of ``axyb-multi`` from its raw fields: the stacks (`validated_stacks`),
    the indices (integers from 0, one per observation, numbering every X and Y without gaps) and
    the optional names (distinct text, one per X / Y). Raises InputError naming what is wrong."""
    A, B = validated_stacks(problem, {k: data[k] for k in STACKS if k in data}, STACKS, min_pairs)
    m = len(A)
    indexes = [_indices(name, data.get(name), m) for name in INDEXES]
    names = [_names(field, data.get(field), int(index.max()) + 1, letter)
             for field, index, letter in zip(NAME_FIELDS, indexes, "XY")]
    scaled_x, scaled_y = scaled_cameras(data.get("camera_scale", "known"), names[0], names[1], *indexes)
    return AXYBMultiData(A, B, indexes[0], indexes[1], names[0], names[1], bool(scaled_x or scaled_y),
                         scaled_x, scaled_y)


def scaled_cameras(value: Any, x_names: tuple[str, ...], y_names: tuple[str, ...], x_index: np.ndarray,
                   y_index: np.ndarray) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The data fact ``camera_scale`` of a cell: "known" (the default: every camera metric) or the
    names of the monocular cameras, each with its own unknown scale (X's: wrist cameras, Y's:
    fixed cameras). Returns the indices of the X's and of the Y's named; InputError naming what is
    wrong (an unknown or ambiguous name, a name given twice, an observation between two named)."""
    if isinstance(value, str) and value == "known":
        return (), ()
    if isinstance(value, str):
        if value == "unknown":
            raise InputError("camera_scale='unknown' does not say which of the cell's X's and Y's are cameras: give "
                             "camera_scale=[the names of the monocular cameras] (fixed cameras are Y's, wrist "
                             "cameras X's), each gets its own scale")
        raise InputError(f"camera_scale={value!r} must be 'known' (every camera metric, the default) or a list of the "
                         "names of the cameras known only up to scale (monocular SLAM), e.g. ['cam0', 'cam2']")
    if isinstance(value, np.ndarray) and value.ndim == 1 and value.dtype.kind in "UO":
        value = value.tolist()
    if not isinstance(value, Sequence) or not all(isinstance(v, str) for v in value):
        raise InputError(f"camera_scale must be 'known' or a list of camera names (text), got {type(value).__name__}")
    twice = sorted({v for v in value if list(value).count(v) > 1})
    if twice:
        raise InputError(f"camera_scale names {twice} more than once; name each monocular camera once")
    scaled_x, scaled_y = [], []
    for name in value:
        in_x, in_y = name in x_names, name in y_names
        if in_x and in_y:
            raise InputError(f"camera_scale names {name!r}, which is both an X and a Y of the cell: give the X's and "
                             "the Y's different names (x_names, y_names)")
        if not (in_x or in_y):
            raise InputError(f"camera_scale names {name!r}, which is no X or Y of the cell; its X's: "
                             f"{', '.join(x_names)}; its Y's: {', '.join(y_names)}")
        (scaled_x.append(x_names.index(name)) if in_x else scaled_y.append(y_names.index(name)))
    both = np.flatnonzero(np.isin(x_index, scaled_x) & np.isin(y_index, scaled_y))
    if len(both):
        i = int(both[0])
        raise InputError(f"camera_scale names both {x_names[x_index[i]]!r} and {y_names[y_index[i]]!r}, which "
                         f"observation {i} ties: one of an observation's X and Y is the camera, the other its target; "
                         "name only the camera")
    return tuple(sorted(scaled_x)), tuple(sorted(scaled_y))


def _indices(name: str, value: Any, m: int) -> np.ndarray:
    if value is None:
        raise InputError(f"{name} is required: one integer per observation (0 for the first "
                         f"{'X' if name == 'x_index' else 'Y'})")
    array = np.asarray(value)
    if array.dtype == bool or array.dtype.kind not in "iu":
        if array.dtype.kind == "f" and array.size and np.all(np.isfinite(array)) and np.all(array == np.round(array)):
            array = array.astype(np.int64)
        else:
            raise InputError(f"{name} must hold integers (0, 1, ...), got {array.dtype} values")
    if array.shape != (m,):
        raise InputError(f"{name} must hold one index per observation ({m}), got shape {array.shape}")
    if array.min() < 0:
        raise InputError(f"{name} must be >= 0, got {int(array.min())} at observation {int(np.argmin(array))}")
    if array.max() >= m:  # every index needs an observation: beyond m - 1 there are gaps (and no bincount of 10^12)
        raise InputError(f"{name} holds {int(array.max())} at observation {int(np.argmax(array))}, but there are only "
                         f"{m} observations: number the unknowns 0, 1, ... without gaps (every index must have an "
                         "observation)")
    used = np.bincount(array)
    if np.any(used == 0):
        gaps = np.flatnonzero(used == 0).tolist()
        raise InputError(f"{name} skips {gaps[:5]}: number the unknowns 0..{len(used) - 1} without gaps (every "
                         "index must have an observation)")
    return _frozen(array.astype(np.int64))


def _names(field: str, value: Any, count: int, letter: str) -> tuple[str, ...]:
    if value is None:
        return tuple(f"{letter}{k}" for k in range(count))
    if isinstance(value, np.ndarray) and value.ndim == 1 and value.dtype.kind in "UO":  # names read from a file
        value = value.tolist()
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise InputError(f"{field} must be a list of {count} names, got {type(value).__name__}")
    names = tuple(value)
    if len(names) != count or not all(isinstance(n, str) and n.strip() for n in names):
        raise InputError(f"{field} must be {count} non-empty names (one per {letter} of the indices), got {len(names)}")
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise InputError(f"{field}: the name(s) {twice} are given twice; each {letter} needs its own")
    return names


def components(x_index: np.ndarray, y_index: np.ndarray, nX: int, nY: int) -> tuple[Component, ...]:  # noqa: N803
    """The connected components of the bipartite graph with an edge (x_i, y_i) per observation
    (union-find over nX + nY nodes), largest first."""
    parent = list(range(nX + nY))

    def root(k: int) -> int:
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    for x, y in set(zip(x_index.tolist(), y_index.tolist())):
        a, b = root(x), root(nX + y)
        if a != b:
            parent[max(a, b)] = min(a, b)
    roots = np.array([root(k) for k in range(nX + nY)])
    out = []
    for r in np.unique(roots):
        x = tuple(int(k) for k in np.flatnonzero(roots[:nX] == r))
        y = tuple(int(k) for k in np.flatnonzero(roots[nX:] == r))
        obs = np.flatnonzero(np.isin(x_index, x))
        out.append(Component(x, y, _frozen(obs)))
    return tuple(sorted(out, key=lambda c: (-len(c.observations), c.x)))


def _kept_rows(stacks: tuple[np.ndarray, np.ndarray], A: np.ndarray, B: np.ndarray) -> np.ndarray | None:
    """The rows of the stacks (A0, B0) that A, B are, in order (each observation of A, B found at
    or after the row of the one before it, compared bit for bit), or None when they are not such
    a subset."""
    A0, B0 = stacks
    if len(A) > len(A0):
        return None

    def keys(P: np.ndarray, Q: np.ndarray) -> list[bytes]:
        rows = np.concatenate([np.reshape(P, (len(P), 16)), np.reshape(Q, (len(Q), 16))], axis=1)
        return [row.tobytes() for row in np.ascontiguousarray(rows, dtype=np.float64)]

    old, new = keys(A0, B0), keys(A, B)
    rows, j = [], 0
    for key in new:
        while j < len(old) and old[j] != key:
            j += 1
        if j == len(old):
            return None
        rows.append(j)
        j += 1
    return np.asarray(rows, dtype=np.int64)


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a
