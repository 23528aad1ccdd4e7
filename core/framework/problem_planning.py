"""The planning part of the problem contract (`PlanningPart`): the Fisher information each
planned station would give, for ``handeye plan`` and ``watch``'s next stations
(`handeye.planning`). Optional: a problem without it cannot plan stations yet."""

from __future__ import annotations

import numpy as np

from handeye.framework.problem_engine import NamedPoses


class PlanningPart:
    """What planning asks of a problem."""

    def station_information(self, A: np.ndarray, B: np.ndarray, unknowns: NamedPoses, robot_sigma: tuple[float, float],
                            camera_cov: np.ndarray, setup: str) -> tuple[np.ndarray, tuple[str, ...], tuple[str, ...]] | None:
        """For planning which stations to record (`handeye.planning`): the Fisher information
        (m, 6k, 6k) that each planned station would give, its robot pose A_i (T_base_flange) and
        camera pose B_i exactly as planned, with the cell's X and Y in `unknowns` (A X = Y B's
        convention for `setup`, docs/conventions.md), the camera pose's covariance camera_cov
        (m, 6, 6) in B_i's own frame and the robot's noise robot_sigma (rad, length per axis);
        with the names of the k unknowns (6 parameters each, rotation then translation in their
        own frame) as the problem calls them, and those of interest (the others are nuisances).
        None (the default): the problem cannot plan stations yet."""
        return None

    @property
    def plans(self) -> bool:
        """Whether the problem can plan stations (`station_information` overridden)."""
        return type(self).station_information is not PlanningPart.station_information
