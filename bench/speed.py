"""Speed benchmark of every registered solver/backend of a problem against OpenCV: ``axyb``
(default) beside OpenCV SHAH and LI, ``axxb`` beside ``cv2.calibrateHandEye``'s five methods.

    python bench/speed.py [--pairs 10,16,100,1000,10000] [--repeats 7] [--solvers kron-lstsq,lmi-sdp/cvxpy]
    python bench/speed.py --problem axxb       # m = 16, 100, 1000

The same as ``handeye bench`` (the code is `handeye.harness.bench`, whose docstring says what is
timed and how; each problem's settings are its `Problem.bench`); bench/README.md holds figures
measured with it.

``--compare-with DIR`` times another version of handeye against this one in the same run: DIR
holds that version as the package ``handeye`` (e.g. a commit's ``core`` with its ``plugins`` and
``problems`` inside, as installed), each version runs in its own process, alternating, for
``--rounds`` rounds, and the table shows per row and m the median and the fastest call of each
and their ratio (a shared machine's load then falls on both alike):

    mkdir -p /tmp/old && git archive HEAD core plugins problems | tar -x -C /tmp/old
    mv /tmp/old/core /tmp/old/handeye && mv /tmp/old/plugins /tmp/old/problems /tmp/old/handeye/
    python bench/speed.py --problem axbycz --solvers auto --pairs 16,100,1000,10000 --compare-with /tmp/old
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from handeye.base.errors import HandEyeError
from handeye.cli import bench_cmd


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = argparse.ArgumentParser(prog="bench/speed.py", description=bench_cmd.__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    bench_cmd.add_arguments(parser)
    parser.add_argument("--compare-with", metavar="DIR",
                        help="also time the handeye package in DIR, alternating with this one (module docstring)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds of --compare-with (default 3)")
    args = parser.parse_args(argv)
    if args.compare_with:
        return compare(argv, Path(args.compare_with), args.rounds)
    try:
        return bench_cmd.run(args)
    except HandEyeError as exc:
        print(f"bench/speed.py: error: {exc}", file=sys.stderr)
        return 2


def _without(argv: list[str], *options: str) -> list[str]:
    """argv without the given options and their values (as ``--opt value`` or ``--opt=value``)."""
    out, skip = [], False
    for a in argv:
        if skip:
            skip = False
        elif a in options:
            skip = True
        elif not a.split("=", 1)[0] in options:
            out.append(a)
    return out


def _timings(argv: list[str], package: Path | None) -> dict[tuple[str, int], list[float]]:
    """One benchmark in a new process (`package`: the directory whose ``handeye`` it imports, None:
    this one): the call times (s) per (row, m)."""
    env = dict(os.environ)
    if package is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(package), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench.json"
        subprocess.run([sys.executable, __file__, *argv, "--json", str(out), "--no-progress"], env=env, check=True,
                       stdout=subprocess.DEVNULL)
        cells = json.loads(out.read_text())["cells"]
    return {(c["row"], c["m"]): list(c["calls"]) for c in cells if c["calls"]}


def compare(argv: list[str], package: Path, rounds: int) -> int:
    """`--compare-with`: both versions alternately for `rounds` rounds; a markdown table of the
    median and fastest call of each and the ratio other / this."""
    if not (package / "handeye" / "__init__.py").is_file():
        print(f"bench/speed.py: error: {package} holds no package handeye/", file=sys.stderr)
        return 2
    argv = _without(argv, "--compare-with", "--rounds", "--json", "--no-progress")
    other: dict[tuple[str, int], list[float]] = {}
    this: dict[tuple[str, int], list[float]] = {}
    for _ in range(rounds):
        for store, where in ((other, package), (this, None)):
            for key, calls in _timings(argv, where).items():
                store.setdefault(key, []).extend(calls)
    print(f"{rounds} rounds, alternating; other = {package}")
    print("| row | m | other: median / fastest [ms] | this: median / fastest [ms] | other / this (median, fastest) |")
    print("|---|---|---|---|---|")
    for key in sorted(this, key=lambda k: (k[0], k[1])):
        if key not in other:
            continue
        a, b = other[key], this[key]
        ma, mb = statistics.median(a), statistics.median(b)
        print(f"| {key[0]} | {key[1]} | {1e3 * ma:.1f} / {1e3 * min(a):.1f} | {1e3 * mb:.1f} / {1e3 * min(b):.1f} | "
              f"{ma / mb:.2f}x, {min(a) / min(b):.2f}x |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
