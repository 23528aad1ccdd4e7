"""The noise model of the simulators.

Rotation noise right-multiplies a pose's rotation by exp([n]_x), n ~ N(0, sigma_rot^2 I3) (rad);
translation noise adds N(0, sigma_trans^2 I3) in data units. Each data stack has its own pair of
standard deviations, so "noise on B only" and "both A and B" are the same model.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from handeye.base.errors import InputError
from handeye.geometry.se3 import Array, so3_exp


@dataclasses.dataclass(frozen=True)
class NoiseModel:
    """Standard deviations per data stack: {"B": (sigma_rot [rad], sigma_trans [units])}."""

    sigmas: Mapping[str, tuple[float, float]] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        for name, pair in self.sigmas.items():
            if len(pair) != 2 or min(pair) < 0 or not np.all(np.isfinite(pair)):
                raise InputError(f"noise for {name} must be (sigma_rot >= 0, sigma_trans >= 0), got {pair}")

    @classmethod
    def on(cls, stacks: str | tuple[str, ...], rot: float, trans: float) -> NoiseModel:
        """The same (rot, trans) noise on each named stack, e.g. ``NoiseModel.on("B", 0.01, 0.5)``."""
        names = (stacks,) if isinstance(stacks, str) else stacks
        return cls({n: (float(rot), float(trans)) for n in names})

    def apply(self, name: str, T: Array, rng: np.random.Generator, factor: Array | None = None) -> Array:
        """A noisy copy of pose stack T: (m, 4, 4) named `name` (unchanged copy if no noise);
        `factor`: (m,) each pose's standard deviations times its own factor (the same draws),
        e.g. the observations of a camera noisier than the others."""
        out = np.array(T, dtype=float, copy=True)
        rot, trans = self.sigmas.get(name, (0.0, 0.0))
        m = len(out)
        scale = 1.0 if factor is None else np.asarray(factor, dtype=float)[:, None]
        if rot > 0:
            out[:, :3, :3] = out[:, :3, :3] @ so3_exp(scale * (rot * rng.standard_normal((m, 3))))
        if trans > 0:
            out[:, :3, 3] += scale * (trans * rng.standard_normal((m, 3)))
        return out
