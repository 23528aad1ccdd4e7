"""``handeye simulate``: write simulated data with its truth (format from the extension).

For ``axyb`` this is the paper's simulation (Sec. IV-A): A_i from the forward kinematics of an
LR Mate 200iD-like arm at random joints (mm), the paper's X and Y, B_i = Y^-1 A_i X, then
Gaussian noise (`handeye.noise.NoiseModel`) on B, A or both.
"""

from __future__ import annotations

import argparse
from typing import Any

from ..errors import InputError
from ..io import save_data, supported_extensions
from ..noise import NoiseModel
from ..registry import get_registry

NAME = "simulate"


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(NAME, help="write simulated data with truth", description=__doc__)
    parser.add_argument("--problem", default="axyb", help="problem to simulate (default axyb)")
    parser.add_argument("--pairs", type=int, default=16, help="number of pose pairs (default 16)")
    parser.add_argument("--noise-rot", type=float, default=0.0, metavar="RAD",
                        help="rotation noise std, rad (default 0)")
    parser.add_argument("--noise-trans", type=float, default=0.0, metavar="MM",
                        help="translation noise std, mm (default 0)")
    parser.add_argument("--noise-on", default="B", metavar="B|A|both",
                        help="data stack(s) the noise is added to: a data field, or 'both' (default B)")
    parser.add_argument("--seed", type=int, default=None, help="random seed (default: fresh)")
    parser.add_argument("-o", "--output", required=True,
                        help=f"output file ({', '.join(supported_extensions())})")
    parser.set_defaults(run=run)
    return parser


def run(args: argparse.Namespace) -> int:
    problem = get_registry().problem(args.problem)
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
    noise = NoiseModel.on(stacks, args.noise_rot, args.noise_trans)
    data, truth = problem.simulate(pairs=args.pairs, seed=args.seed, noise=noise)
    description = (f"handeye simulate --problem {args.problem} --pairs {args.pairs} --noise-rot "
                   f"{args.noise_rot} --noise-trans {args.noise_trans} --noise-on {args.noise_on} "
                   f"--seed {args.seed}")
    path = save_data(args.output, data, truth, problem=args.problem,
                     metadata={"units": "mm", "setup": "eye-in-hand", "description": description,
                               "source": "simulated by handeye"})
    print(f"wrote {args.pairs} {args.problem} pairs with truth to {path}")
    return 0
