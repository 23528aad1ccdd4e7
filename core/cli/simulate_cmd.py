"""``handeye simulate``: write simulated data with its truth (format from the extension).

For ``axyb`` this is the paper's simulation (Sec. IV-A): A_i from the forward kinematics of an
LR Mate 200iD-like arm at random joints (mm), the paper's X and Y, B_i = Y^-1 A_i X, then
Gaussian noise (`handeye.estimation.noise.NoiseModel`) on B, A or both.

For ``axxb`` the same arm and cell (eye-in-hand) record absolute poses at stations, noise goes on
the robot poses (``--noise-on A``), the camera poses (``B``, the default) or both, and the file
holds the relative motions A, B made from them (``--pairs M`` stations; ``--pairing`` all, the
default: M (M - 1) / 2 motions, or consecutive: M - 1). The truth is X = T_flange_cam.

With ``--stations N`` (``axyb`` and ``axxb``) the file holds the N stations' absolute poses
themselves, as a cell records them (robot_poses = T_base_flange, camera_poses = T_cam_target,
setup eye-in-hand; docs/formats.md), so the same file can be solved as AX=YB
(``--problem axyb``) and as AX=XB (``--problem axxb``).

A file holds at most 1,000,000 pairs, motions or stations (with ``--pairing all``, M stations
make M (M - 1) / 2 motions); an existing output file is kept unless ``--force`` is given.
"""

from __future__ import annotations

import argparse
from typing import Any

from handeye.base.errors import InputError
from handeye.cli._common import (
    add_force_flag,
    check_outputs,
    finite_number,
    seed_number,
    whole_number,
)
from handeye.estimation.noise import NoiseModel
from handeye.geometry.kinematics import simulate_stations
from handeye.geometry.se3 import inverse
from handeye.host.api import plugin_faults
from handeye.host.registry import get_registry
from handeye.io.data_files import (
    DEFAULT_PAIRING,
    PAIRINGS,
    save_data,
    station_readers,
    supported_extensions,
)

NAME = "simulate"
#: Most pairs, motions or stations one simulated file holds. Measured: 10^5 pairs take 7 s, 0.23 GB
#: of memory and 56 MB as JSON (NPZ: about a third of each), so the cap costs ~1 min and ~2 GB at
#: most; far more than any calibration uses (tens to hundreds of poses), while a mistyped count
#: (10^9) would otherwise end in a MemoryError after minutes.
MAX_POSES = 1_000_000


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(NAME, help="write simulated data with truth", description=__doc__,
                                   formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--problem", default=None,
                        help="registered problem to simulate (handeye list shows them; default: the default problem, "
                             "A_i X = Y B_i)")
    parser.add_argument("--pairs", type=whole_number, default=None,
                        help="number of pose pairs (stations; a problem solved from motions makes them from the "
                             "stations) (default 16)")
    parser.add_argument("--stations", type=whole_number, default=None, metavar="N",
                        help="write the absolute poses of N stations (robot_poses, camera_poses) instead of the "
                             "problem's data; they serve every problem read from a cell's stations")
    parser.add_argument("--pairing", choices=PAIRINGS, default=None,
                        help=f"a problem solved from motions: motions between consecutive stations or all pairs i < j "
                             f"(default {DEFAULT_PAIRING}); with --stations it is recorded in the file")
    parser.add_argument("--noise-rot", type=finite_number, default=0.0, metavar="RAD",
                        help="rotation noise std, rad (default 0)")
    parser.add_argument("--noise-trans", type=finite_number, default=0.0, metavar="MM",
                        help="translation noise std, mm (default 0)")
    parser.add_argument("--noise-on", default="B", metavar="B|A|both",
                        help="data stack(s) the noise is added to: a data field, or 'both' (default B; "
                             "axxb: A = the robot poses, B = the camera poses)")
    parser.add_argument("--seed", type=seed_number, default=None, help="random seed (default: fresh)")
    parser.add_argument("-o", "--output", required=True,
                        help=f"output file ({', '.join(supported_extensions())}); an existing one is kept "
                             "unless --force")
    add_force_flag(parser)
    parser.set_defaults(run=run)
    return parser


def run(args: argparse.Namespace) -> int:
    registry = get_registry()
    args.problem = args.problem or registry.default_problem()
    problem = registry.problem(args.problem)
    fields = tuple(problem.data_fields)
    if args.noise_on in ("both", "all"):
        stacks = fields
    else:
        stacks = tuple(s.strip() for s in args.noise_on.split(","))
        unknown = [s for s in stacks if s not in fields]
        if unknown:
            raise InputError(f"--noise-on {args.noise_on!r}: {unknown} not a data field of "
                             f"{args.problem!r}; use one of {list(fields)} or 'both'")
    for name in ("noise_rot", "noise_trans"):
        value = getattr(args, name)
        if not value >= 0 or value == float("inf"):
            raise InputError(f"--{name.replace('_', '-')} must be a finite number >= 0, got {value}")
    if args.problem not in station_readers() and args.stations is not None:
        raise InputError(f"--stations applies to problems {sorted(station_readers())}, not {args.problem!r}")
    motions = args.problem in station_readers() and station_readers()[args.problem].pairing
    if args.pairing is not None and not motions:
        raise InputError(f"--pairing applies to problems whose data are motions "
                         f"({sorted(p for p, c in station_readers().items() if c.pairing)}), not {args.problem!r}")
    if args.stations is not None and args.pairs is not None:
        raise InputError("give --pairs (data made from the stations) or --stations (the absolute poses), not both")
    _check_size(args, motions)
    check_outputs([("-o", args.output)], [], args.force)
    noise = NoiseModel.on(stacks, args.noise_rot, args.noise_trans)
    metadata = {"units": "mm", "setup": "eye-in-hand", "source": "simulated by handeye"}
    options = {"pairing": args.pairing} if args.pairing is not None else {}
    if args.stations is not None:
        # the simulated cell's stations: noise "A" on the robot poses, "B" on the camera poses
        stations, truth = simulate_stations(args.stations, seed=args.seed, noise=noise)
        data = {"robot_poses": stations["A"], "camera_poses": inverse(stations["B"])}
        count, what, size = args.stations, "stations", f"--stations {args.stations}"
    else:
        pairs = 16 if args.pairs is None else args.pairs
        with plugin_faults(f"problem {args.problem!r}", registry.problem_is_builtin(args.problem),
                           registry.problem_provider(args.problem)):
            data, truth = problem.simulate(pairs=pairs, seed=args.seed, noise=noise, **options)
        count, what, size = len(data["A"]), ("motions" if motions else "pairs"), f"--pairs {pairs}"
    if motions:
        metadata["pairing"] = args.pairing or DEFAULT_PAIRING
    metadata["description"] = (
        f"handeye simulate --problem {args.problem} {size}"
        + (f" --pairing {metadata['pairing']}" if "pairing" in metadata else "")
        + f" --noise-rot {args.noise_rot} --noise-trans {args.noise_trans} --noise-on {args.noise_on} --seed {args.seed}")
    # a file of stations carries the cell's truth (X, Y of AX=YB) and serves every problem reading
    # absolute poses (docs/formats.md); it is validated as the default problem's data it also is
    saved_as = registry.default_problem() if args.stations is not None else args.problem
    path = save_data(args.output, data, truth, problem=saved_as,
                     metadata=metadata, force=args.force)
    print(f"wrote {count} {args.problem} {what} with truth to {path}")
    return 0


def _check_size(args: argparse.Namespace, motions: bool) -> None:
    """InputError when the file would hold more than `MAX_POSES` pairs, motions or stations."""
    if args.stations is not None:
        flag, count, what = "--stations", args.stations, "stations"
    else:
        flag, count, what = "--pairs", 16 if args.pairs is None else args.pairs, "pairs"
        if motions and count > 1:
            every = (args.pairing or DEFAULT_PAIRING) == "all"
            count, what = (count * (count - 1) // 2 if every else count - 1), "motions"
    if count < 1:
        raise InputError(f"{flag} takes a number of {what} >= 1, got {count}")
    if count > MAX_POSES:
        value = args.stations if args.stations is not None else args.pairs
        made = f" makes {count} {what}" if what == "motions" else ""
        hint = " (or --pairing consecutive)" if what == "motions" else ""
        raise InputError(f"{flag} {value}{made}: a simulated file holds at most {MAX_POSES} {what}; "
                         f"give a smaller {flag}{hint}")
