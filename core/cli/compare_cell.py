"""``handeye compare --cell FILE`` / ``--real``: every solver ranked on real recordings, which
have no truth, by what they predict of stations they were not fitted to.

- ``--cell FILE`` (a cell file, as ``handeye calibrate --config`` reads it, of one camera): board
  images are ranked by held-out board corners (`handeye.harness.crossval_images`), a pose file by
  held-out residuals (`handeye.harness.crossval`, as ``--data``);
- ``--real``: every real recording handeye bundles, each as above: the ETH robot_arm pose pairs
  (``--example eth-robot-arm``) and the industrial_calibration circle-grid images
  (`handeye.io.examples.image_example_dir`).

Every registered solver takes part, a third party's too (``--solvers`` narrows them), beside
OpenCV's methods one by one and, for images, what ``handeye calibrate`` answers (``default``).
Files are written at the end, whole, to ``-o OUTDIR``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from handeye.base.errors import InputError
from handeye.cli._common import check_new_results, check_outputs_apart

#: the bundled image example's board and pose files (`handeye.io.examples.image_example_dir`)
IMAGE_EXAMPLE_BOARD = "circlegrid:10x10:25.4mm"
IMAGE_EXAMPLE_NAME = "rct-circle-grid"
POSE_EXAMPLE_NAME = "eth-robot-arm"
DEFAULT_FOLDS = 5


def image_example_cell() -> Any:
    """The bundled circle-grid recording as a cell (eye-in-hand, images paired by name)."""
    from handeye.io.examples import image_example_dir
    from handeye.workflow.cell import Cell, Images, Matching, PoseStream

    folder = image_example_dir()
    return Cell(robot=PoseStream(folder / "poses", format="xyz-quat-xyzw", unit="m"),
                images=Images(folder / "images", board=IMAGE_EXAMPLE_BOARD), setup="eye-in-hand",
                matching=Matching(method="name"))


def run(args: argparse.Namespace) -> int:
    """The ranking of `args.cell`, or of every bundled real recording (`args.real`)."""
    from handeye.cli.compare_data import check_flags
    from handeye.workflow.cell import Cell

    check_flags(args)
    if args.real:
        jobs = [(IMAGE_EXAMPLE_NAME, image_example_cell()), (POSE_EXAMPLE_NAME, None)]
    else:
        cell = Cell.from_file(args.cell)
        jobs = [(args.name or Path(args.cell).stem, cell)]
    for name, cell in jobs:
        if cell is None:  # the bundled pose pairs: as --example
            _pose_example(args, name)
        else:
            _cell(args, name, cell)
    return 0


def _cell(args: argparse.Namespace, name: str, cell: Any) -> None:
    from handeye.harness.crossval_images import (
        FILES,
        image_specs,
        run_image_crossval,
        write_image_crossval,
    )
    from handeye.workflow.calibration import read_stations

    if cell.joints is not None or cell.observations is not None:
        raise InputError("compare --cell ranks solvers on a cell of one camera (board images or a pose file); a cell "
                         "of joint readings or of several cameras' observations is not supported here")
    if cell.images is None:
        return _pose_cell(args, name, cell)
    files = [name + suffix for suffix in FILES]
    check_outputs_apart([("-o", Path(args.output) / f) for f in files], [args.cell])
    check_new_results("-o", args.output, files, args.force)
    specs = image_specs(cell.problem, _solvers(args, cell.problem))
    read = read_stations(cell)
    result = run_image_crossval(cell.problem, read.pose_file.data, read.stations.images.observations, specs,
                                facts=read.facts,
                                folds=args.folds or DEFAULT_FOLDS, seed=args.seed or 0, timeout=_timeout(args),
                                source=f"images {cell.images.folder}")
    paths = write_image_crossval(result, Path(args.output), name)
    failed = sum(bool(r["failed"]) for r in result.rows)
    print(f"{name}: held-out board corners of {len(specs)} contender(s) over {result.folds} folds of "
          f"{result.stations} stations ({result.corners} corners), seed {result.seed}; {failed} failed on some fold; "
          f"{result.seconds:.1f} s")
    print()
    from handeye.harness.crossval_images import corners_table

    print(corners_table(result))
    print("Each contender fitted on the other folds' stations predicts the corners of the held-out images through "
          "its X, Y and their robot poses: lower is better (docs/harness.md).")
    for key in ("table", "folds", "json"):
        print(f"{key:>7}: {paths[key]}")
    print()
    sys.stdout.flush()


def _pose_cell(args: argparse.Namespace, name: str, cell: Any) -> None:
    from handeye.cli.compare_data import TO_MM, report
    from handeye.harness.crossval import CrossValData
    from handeye.io.data_files import station_readers
    from handeye.workflow.calibration import read_stations

    pose_file = read_stations(cell).pose_file
    metadata = pose_file.metadata
    cv = CrossValData(cell.problem, pose_file.data, None, pose_file.poses, metadata.get("setup"),
                      metadata.get("pairing"), station_readers().get(cell.problem), TO_MM.get(metadata.get("units", "")))
    report(args, cv, f"cell {args.cell}", name, cell.problem)


def _pose_example(args: argparse.Namespace, name: str) -> None:
    from handeye.cli.compare_data import read, report
    from handeye.io.examples import EXAMPLE_PROBLEM

    args.example, args.problem = name, EXAMPLE_PROBLEM
    cv, source = read(args)
    report(args, cv, source, name, EXAMPLE_PROBLEM)


def _solvers(args: argparse.Namespace, problem: str) -> Any:
    from handeye.harness import parse_specs

    return parse_specs(args.solvers, problem) if args.solvers else None


def _timeout(args: argparse.Namespace) -> float | None:
    return 30.0 if args.timeout is None else (args.timeout if args.timeout > 0 else None)
