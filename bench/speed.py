"""Speed benchmark of every registered solver/backend of a problem against OpenCV: ``axyb``
(default) beside OpenCV SHAH and LI, ``axxb`` beside ``cv2.calibrateHandEye``'s five methods.

    python bench/speed.py [--pairs 10,16,100,1000,10000] [--repeats 7] [--solvers kron-lstsq,lmi-sdp/cvxpy]
    python bench/speed.py --problem axxb       # m = 16, 100, 1000

The same as ``handeye bench`` (the code is `handeye.harness.bench`, whose docstring says what is
timed and how; each problem's settings are its `Problem.bench`); bench/README.md holds figures
measured with it.
"""

from __future__ import annotations

import argparse
import sys

from handeye.cli import bench_cmd
from handeye.framework.errors import HandEyeError


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench/speed.py", description=bench_cmd.__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    bench_cmd.add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return bench_cmd.run(args)
    except HandEyeError as exc:
        print(f"bench/speed.py: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
