"""The evaluation harness: compare registered solvers on simulated data, as the paper's Sec. IV-A.

::

    from handeye.harness import Study, Sweep, Spec, run_study, write_report
    study = Study(specs=(Spec("kron-lstsq"), Spec("lmi-sdp", "picos")),
                  sweeps=(Sweep("noise", levels=(0.0, 0.01, 0.05), pairs=(16,)),), trials=5)
    result = run_study(study, jobs=2)          # StudyResult: .records, .summary(), .to_csv()
    write_report(result, "out/")               # CSV, JSON summary, PNG figures, markdown tables

`study` defines studies (and the built-in ones: the paper's, the default sweeps, the accuracy
study of any problem), `runner` runs them (processes or dask), `result` holds the records,
`report` draws and tabulates. Every part is generic over the registered problems (``axyb``,
``axxb``, a third party's). docs/harness.md has the study file format and the record columns;
docs/reproducing-the-paper.md the paper's study.
"""

from __future__ import annotations

from handeye.harness.report import error_table, plot_study, time_table, write_report
from handeye.harness.result import StudyResult, read_csv
from handeye.harness.runner import data_seed, run_study, run_unit, units_of
from handeye.harness.study import (
    ACCURACY_NOISE,
    ACCURACY_PAIRS,
    CENTERS,
    PAPER_METHODS,
    PAPER_MM_PER_RAD,
    PAPER_OPTIONS,
    PAPER_PAIRS,
    UNITS,
    GridPoint,
    Spec,
    Study,
    Sweep,
    accuracy_study,
    default_specs,
    missing_paper_methods,
    paper_noise,
    paper_specs,
    paper_study,
    sweep_study,
)
from handeye.harness.study_files import (
    load_study,
    parse_floats,
    parse_ints,
    parse_specs,
    study_from_dict,
)

__all__ = [
    "ACCURACY_NOISE",
    "ACCURACY_PAIRS",
    "CENTERS",
    "PAPER_METHODS",
    "PAPER_MM_PER_RAD",
    "PAPER_OPTIONS",
    "PAPER_PAIRS",
    "UNITS",
    "GridPoint",
    "Spec",
    "Study",
    "StudyResult",
    "Sweep",
    "accuracy_study",
    "data_seed",
    "default_specs",
    "error_table",
    "load_study",
    "missing_paper_methods",
    "paper_noise",
    "paper_specs",
    "paper_study",
    "parse_floats",
    "parse_ints",
    "parse_specs",
    "plot_study",
    "read_csv",
    "run_study",
    "run_unit",
    "study_from_dict",
    "sweep_study",
    "time_table",
    "units_of",
    "write_report",
]
