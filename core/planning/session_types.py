"""What a recording session reports (`handeye.planning.session.Session`): the target precision
(`Tolerance`), a station that disagrees (`Disagreement`), the next stations to record
(`Suggestions`) and the update after each station (`Update`)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from handeye.base.errors import InputError


class SessionError(InputError):
    """A session was set up or fed wrongly (unknown problem or setup, a bad pose or tolerance)."""


@dataclasses.dataclass(frozen=True)
class Tolerance:
    """The target precision: 1-sigma of rotation (deg) and translation (the data's unit)."""

    rotation_deg: float
    translation: float

    def __post_init__(self) -> None:
        for name in ("rotation_deg", "translation"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf:
                raise SessionError(f"the target {name.replace('_deg', '')} must be a positive number, got {value!r}")

    def met(self, std: dict[str, dict[str, float]]) -> bool:
        """Whether every 1-sigma in `std` is within the tolerance."""
        return all(s["rotation_deg"] <= self.rotation_deg and s["translation"] <= self.translation
                   for s in std.values())


@dataclasses.dataclass(frozen=True)
class Disagreement:
    """A station that disagrees with the others: its index (0-based) and name, its whitened
    residual (chi-square on 6 degrees of freedom) and the probability of one as large, and its
    residual itself: rotation (deg) and translation (the data's unit) between A X and Y B."""

    station: int
    name: str
    chi2: float
    p_value: float
    rotation_deg: float
    translation: float

    def describe(self) -> str:
        return (f"station {self.name} disagrees with the others: off by {self.rotation_deg:.3g} deg and "
                f"{self.translation:.3g} (chi-square {self.chi2:.3g} on 6 degrees of freedom, p = {self.p_value:.1e}); "
                "left out of the answer")


@dataclasses.dataclass(frozen=True)
class Suggestions:
    """The next stations to record, in order: A (k, 4, 4) robot poses T_base_flange, B (k, 4, 4)
    the camera poses they should give, views (k, 4, 4) T_cam_target; std: the predicted 1-sigma
    after recording them (the information of the 1-sigma reported, plus theirs at the expected
    noise)."""

    A: np.ndarray
    B: np.ndarray
    views: np.ndarray
    std: dict[str, dict[str, float]]


@dataclasses.dataclass(frozen=True)
class Update:
    """What a session knows after a station (module docstring).

    station, name: the station added (0-based index); stations: recorded so far; used: kept in
    the answer. unknowns: {name: 4x4} of the problem's unknowns of interest (A X = Y B: X and Y;
    A X = X B: X, the camera's pose), None while undetermined. std: {name: {rotation_deg,
    translation}} of the same, None while unknown; noise: where their noise comes from,
    "estimated" (the residuals), "expected" (the stated noise) or "unknown". enough: the target
    is reached. disagreement: the station disagrees (left out), else None. suggestions: the next
    stations, or None. solved: a full handeye.solve ran; readmitted: stations left out before
    that agree with its answer (under the noise estimated since) and are back in. warnings: e.g.
    why there are no suggestions. seconds: time taken.
    """

    station: int
    name: str
    stations: int
    used: int
    unknowns: dict[str, np.ndarray] | None
    std: dict[str, dict[str, float]] | None
    noise: str
    enough: bool
    disagreement: Disagreement | None
    suggestions: Suggestions | None
    solved: bool
    readmitted: tuple[str, ...]
    warnings: tuple[str, ...]
    seconds: float
