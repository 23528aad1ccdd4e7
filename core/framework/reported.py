"""What core reads from a solver's diagnostics: the contract from solver plugins to the host,
the self-check, the workflow and the report, typed and read in one place.

A solver reports in `SolverOutput.diagnostics`, a JSON-ready dict that is the user's record of
the solve. A few of its entries decide things in core (a status, a check skipped, a scale
applied, a row listed); `Reported.of` reads those, each under the key named here once, so that
core never looks a solver's key up itself and a plugin author finds in one place what core
understands. A solver writes (all optional):

- ``warnings``: list of text, in the user's words;
- ``outliers``: the rows it left out, ``[{"index": i, ...}]`` (0-based rows of the data), and
  ``outlier_test``: how it found them (the report shows it);
- ``held_out``: its own held-out evidence, ``{"best": True, ...}`` when the answer predicts
  measurements of stations it was not fitted to at least as well as every alternative it
  compared; ``drift_held_out``: ``{"drift_agrees": True, ...}`` when the answer from consecutive
  motions agrees with held-out stations (auto);
- ``formulation``: present when it fitted the stations rather than the pairs (auto);
- ``rotation_blocks``: per unknown ``{"singular_values": [...], "det": d}`` of the rotation block
  it projected onto SO(3) (the self-check's sign of a broken estimate);
- ``camera_scale``, ``camera_scale_std``: the camera's translation scale it fitted (one camera),
  or ``camera_scales``, ``camera_scales_std``: {camera or marker: scale} (a cell), with
  ``camera_scales_held_out``, the held-out comparison that chose them;
- ``sigma_from``: ``"stations"`` when its stated 1-sigma already covers the spread over groups
  of stations; ``fitted_to``: what it fitted (``"poses"``, the default, or e.g. ``"corners"``);
  ``noise_model``: ``"sources"`` when it estimated the noise of each pose, camera and marker;
- ``std``: per unknown {"rotation": rad, "translation": data unit}, its 1-sigma (auto: under
  ``refine``, whose ``noise_model`` is read too);
- ``kinematics``: the arm's fitted kinematics (the kinematic problem's solvers).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any


@dataclasses.dataclass(frozen=True)
class Reported:
    """The entries of a solver's diagnostics core reads (module docstring), typed; absent
    entries take their defaults (`outliers` None: the solver tested for none)."""

    warnings: tuple[str, ...] = ()
    outliers: tuple[Mapping[str, Any], ...] | None = None
    outlier_test: Any = None
    held_out: Mapping[str, Any] | None = None
    drift_agrees: bool = False
    on_stations: bool = False
    rotation_blocks: Mapping[str, Mapping[str, Any]] = dataclasses.field(default_factory=dict)
    camera_scale: float | None = None
    camera_scale_std: float | None = None
    camera_scales: Mapping[str, float] = dataclasses.field(default_factory=dict)
    camera_scales_std: Mapping[str, float] = dataclasses.field(default_factory=dict)
    camera_scales_held_out: Any = None
    sigma_from: str | None = None
    fitted_to: str = "poses"
    noise_model: str | None = None
    std: Mapping[str, Mapping[str, float]] = dataclasses.field(default_factory=dict)
    kinematics: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    @classmethod
    def of(cls, diagnostics: Mapping[str, Any]) -> Reported:
        """The entries core reads of `diagnostics` (a solver's, or a `Solution`'s)."""
        d = diagnostics
        refine = d.get("refine") if isinstance(d.get("refine"), Mapping) else {}
        drift = d.get("drift_held_out")
        held_out = d.get("held_out")
        scale = d.get("camera_scale")
        scale_std = d.get("camera_scale_std")
        return cls(
            warnings=tuple(str(w) for w in d.get("warnings") or ()),
            outliers=None if d.get("outliers") is None else tuple(o for o in d["outliers"] if isinstance(o, Mapping)),
            outlier_test=d.get("outlier_test"),
            held_out=held_out if isinstance(held_out, Mapping) else None,
            drift_agrees=isinstance(drift, Mapping) and drift.get("drift_agrees") is True,
            on_stations="formulation" in d,
            rotation_blocks=d.get("rotation_blocks") or {},
            camera_scale=None if scale is None else float(scale),
            camera_scale_std=None if scale_std is None else float(scale_std),
            camera_scales=d.get("camera_scales") or {},
            camera_scales_std=d.get("camera_scales_std") or {},
            camera_scales_held_out=d.get("camera_scales_held_out"),
            sigma_from=d.get("sigma_from"),
            fitted_to=d.get("fitted_to", "poses"),
            noise_model=d.get("noise_model") or refine.get("noise_model"),
            std=d.get("std") or refine.get("std") or {},
            kinematics=d.get("kinematics") or {},
        )

    @property
    def left_out(self) -> set[int]:
        """The rows (0-based) the solver left out as outliers."""
        return {int(o["index"]) for o in self.outliers or () if "index" in o}

    @property
    def held_out_best(self) -> Mapping[str, Any] | None:
        """The solver's held-out evidence when it says that the answer predicts measurements of
        stations it was not fitted to at least as well as every alternative it compared
        (``best``, with ``answer_px`` and ``others_px``), else None."""
        return self.held_out if self.held_out is not None and self.held_out.get("best") is True else None

    @property
    def scales_fitted(self) -> bool:
        """Whether the solver fitted the camera's scale, or some cameras' or markers' own."""
        return self.camera_scale is not None or bool(self.camera_scales)
