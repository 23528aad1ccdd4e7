"""The studies' and benchmarks' part of the problem contract (`StudyPart`): the noise of the
accuracy study, the simulator's protocols studies sweep, and what `handeye bench` times
(`BenchSettings`, with its rows `BenchRow` and targets `BenchTarget`). Every field has a default:
a problem that sets none is studied and benchmarked as its solvers on its own simulator."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any, ClassVar


@dataclasses.dataclass(frozen=True)
class BenchRow:
    """A row `handeye bench` times beside the registered solvers: one solve done outside handeye
    (e.g. OpenCV called directly), so that handeye's time reads against it.

    call: ``call(inputs)`` prepares one solve of `inputs` (the second item `BenchSettings.simulate`
        returns: the data fields unless the problem makes other inputs) and returns a function of
        no argument doing it; only that function is timed (its result is ignored). It may raise:
        the row then shows the error.
    missing: why the row cannot run here (e.g. a library missing), or None: it can. Rows giving
        the same reason are listed once, together.
    same_method: the registered solver implementing the same method (e.g. ``"tsai"`` beside
        OpenCV's TSAI), whose call time the printout divides by this row's; None: no such solver.
    """

    label: str
    call: Callable[[Mapping[str, Any]], Callable[[], Any]]
    missing: Callable[[], str | None] = lambda: None
    same_method: str | None = None


@dataclasses.dataclass(frozen=True)
class BenchTarget:
    """A speed target `handeye bench` checks and prints: `solver` (on its default backend, or
    `backend`) at `pairs` pairs within `seconds` per `handeye.solve` call, or within `ratio` times
    the call of the row labelled `against` (None: the reference row; e.g. a direct row, to compare
    with the other library called as its users call it); `options` (e.g.
    ``(("init", "kron-lstsq"),)``) make it a row of its own, timed beside the solver's plain row."""

    solver: str
    pairs: int
    seconds: float | None = None
    ratio: float | None = None
    backend: str | None = None
    options: tuple[tuple[str, Any], ...] = ()
    against: str | None = None


@dataclasses.dataclass(frozen=True)
class BenchSettings:
    """What `handeye bench` (`handeye.harness.bench`) times for a problem besides every
    registered solver, and on which data. Every field has a default: a problem that sets none is
    benchmarked as its solvers on its own simulator.

    pairs: the default numbers of pairs m (the ``--pairs`` of the command line).
    reference: the label of the row the ratio column divides by (None: the first row timed);
        reference_name: how the targets name it (None: its label).
    solver_rows: options of registered solvers timed as rows of their own, e.g.
        ``("opencv", (("method", "shah"),))``, labelled ``opencv [method=shah]``, on the solver's
        default backend; always timed (whatever ``--solvers`` selects), left out when the solver
        is not registered for the problem, and a note when its backend is unavailable. A solver
        named here is timed as these rows only.
    direct_rows: solves outside handeye (`BenchRow`), timed after the solver rows.
    targets: `BenchTarget`, judged and printed one line each.
    simulate: ``simulate(pairs=m, seed=seed, noise=noise, **options) -> (data fields, inputs)``,
        called like `Problem.simulate` (``options``: a solver's `SolverSpec.simulate_options`)
        but giving, instead of the truth, the inputs of the direct rows (`BenchRow.call`): e.g.
        the stations a function forms the motions from itself. None: the problem's simulator,
        the data fields serving as both.
    data_note: how the printout describes the data: a `str.format` template of ``{seed}``,
        ``{rot}`` and ``{trans}`` (the noise std, rad and data units). None: the problem's
        simulator with noise on every data stack.
    """

    pairs: tuple[int, ...] = (10, 100, 1000)
    reference: str | None = None
    reference_name: str | None = None
    solver_rows: tuple[tuple[str, tuple[tuple[str, Any], ...]], ...] = ()
    direct_rows: tuple[BenchRow, ...] = ()
    targets: tuple[BenchTarget, ...] = ()
    simulate: Callable[..., tuple[Mapping[str, Any], Mapping[str, Any]]] | None = None
    data_note: str | None = None


class StudyPart:
    """What studies (`handeye.harness`) and `handeye bench` ask of a problem; optional."""

    #: the accuracy study's realistic noise per data stack, (rad, data units); None: 0.002 rad
    #: and 0.5 units (a camera's) on every stack
    study_noise: ClassVar[Mapping[str, tuple[float, float]] | None] = None
    #: simulator protocols (values of its ``protocol`` option) studies sweep one by one; empty: none
    protocols: ClassVar[tuple[str, ...]] = ()
    #: what `handeye bench` times for this problem (default: every registered solver)
    bench: ClassVar[BenchSettings] = BenchSettings()
