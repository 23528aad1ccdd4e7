"""Kinematic calibration with hand-eye (``axyb-kinematic``): how much the arm's own DH
errors cost the pose-only answer, and what fitting them gives back.

The study: the simulator's default cell (`AXYBKinematic.simulate`: the LR Mate 200iD-like arm,
the paper's X and Y, eye in hand), true DH = nominal + errors on the 17 identifiable parameters
(joint offsets and twists 0.1-0.5 deg, lengths a, d 0.2-1 mm, random signs), joint readings
with `--joint-noise` deg of noise, camera poses B with 0.002 rad / 0.5 mm per axis (the accuracy
study's camera). Per trial (seed) and number of stations:

- ``pose-only``: axyb's ``auto`` on (A, B), A the controller's nominal forward kinematics;
- ``free``: ``kinematic-lm`` with ``prior="none"`` (every identifiable correction fitted freely);
- ``kinematic``: ``kinematic-lm`` (the regularised fit: the corrections' prior estimated from
  the stations, `handeye.plugins.kinematic_lm.prior`);
- ``auto``: axyb-kinematic's ``auto`` (the regularised fit, or the pose-only answer where the
  likelihood ratio does not see the arm's errors).

Printed per size: median and 90th percentile of the X and Y errors (rotation deg, translation
mm) and the ratio pose-only / kinematic; for the kinematic fit the error of the identified DH
corrections against the truth (median and largest over the parameters and trials: deg for
angles, mm for lengths), the share of parameters within 2 and 3 standard deviations of their
truth (what the reported covariance is worth), and the median solve time.

``--kinhec``: KinHEC's robot_error track instead (``pip install kinhec``), made on the fly by
`kinhec.generator.generate_sequence` (about 1 s a sequence; kept as npz under ``--cache``).
``--tier small``: 24 sequences, UR5e and iiwa7, eye in hand. ``--tier medium``: 576 sequences,
UR5e, UR10e, Panda, iiwa14, IRB 120 and PUMA 560, eye in hand and eye to hand, 2 repeats of 4
joint-noise levels (1e-4 to 5e-3 rad, no DH errors) and of a 5 x 4 grid of DH errors (every
parameter, std 0.05-3 mm x 0.01-0.3 deg, joints 1e-4 rad); the Panda's table is modified DH and
is skipped; ``--limit N`` takes N per arm and setup at random (seed 0). Every tier: 30
stations, camera 2 mrad and 1, 1, 3 mm per axis. KinHEC's tool transform (flange <- last DH
frame) is constant, so it is folded into X; its q_sign into q. X and Y errors against KinHEC's
truth, which includes what hand-eye data cannot see (the DH errors of the base and of the last
joint): ``floor`` is that part (the visible truth, `canonical`, against KinHEC's), ``... vs
seen`` the errors against the visible truth, ``oracle`` axyb's auto with the arm's visible
errors known (A from the true links): what a kinematic calibration could reach at best.

Usage: python bench/kinematic.py [--trials 20] [--sizes 20,50] [--joint-noise 0.005]
       python bench/kinematic.py --kinhec [--tier medium --limit 12] [--out results.json]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.kinematics import LR_MATE_200ID, DHArm
from handeye.geometry.se3 import inverse
from handeye.problems.axyb_kinematic import PROBLEM, canonical, chain, random_errors


def trial(m: int, seed: int, joint_noise_deg: float) -> dict:
    """Errors of the pose-only and the kinematic answer on one simulated cell."""
    table = LR_MATE_200ID.table
    errors = random_errors(table, np.random.default_rng(10_000 + seed))
    noise = NoiseModel({"A": (math.radians(joint_noise_deg), 0.0), "B": (0.002, 0.5)})
    data, truth = PROBLEM.simulate(pairs=m, seed=seed, noise=noise, errors=errors)
    start = time.perf_counter()
    sol = handeye.solve("axyb-kinematic", solver="kinematic-lm", **data)
    seconds = time.perf_counter() - start
    free = handeye.solve("axyb-kinematic", solver="kinematic-lm", prior="none", **data)
    auto = handeye.solve("axyb-kinematic", **data)
    pose = handeye.solve("axyb", A=data["A"], B=data["B"])
    out = {"seconds": seconds, "status": sol.status.value, "auto answer": auto.diagnostics["answer"].split()[0]}
    for label, unknowns in (("pose-only", pose.unknowns), ("free", free.unknowns), ("kinematic", sol.unknowns),
                            ("auto", auto.unknowns)):
        err = PROBLEM.errors({**unknowns, "links": data["dh"].links()}, truth)
        out[label] = [math.degrees(err["X"]["rotation"]), err["X"]["translation"],
                      math.degrees(err["Y"]["rotation"]), err["Y"]["translation"]]
    truth_flat = errors.ravel()
    rows = []
    for p in sol.diagnostics["kinematics"]["parameters"]:
        joint, kind = p["name"].split()
        k = 4 * (int(joint[1:]) - 1) + LR_MATE_200ID.COLUMNS.index(kind)
        miss = p["correction"] - truth_flat[k]
        scale = 1.0 if p["unit"] == "length" else 180.0 / math.pi
        rows.append((p["unit"], abs(miss) * scale, abs(miss) / p["std"]))
    out["parameters"] = rows
    return out


def kinhec_inputs(cfg, cache: Path | None) -> dict | None:
    """One KinHEC robot_error sequence as the solver's inputs and the truth: A (nominal FK of the
    readings), B (eye in hand T_target_cam, eye to hand T_cam_target), q (q_sign folded in), the
    nominal and true DH tables, KinHEC's X, Y and its tool transform; cached as npz under `cache`
    (generation takes about a second). None: the arm's table is not standard DH (Panda)."""
    from kinhec import se3 as kse3
    from kinhec.generator import generate_sequence
    from kinhec.robots import get_robot

    robot = get_robot(cfg.robot)
    if robot.convention != "standard":
        return None
    path = cache / f"{cfg.sequence_id}.npz" if cache else None
    if path is not None and path.exists():
        return {k: (v.item() if v.ndim == 0 else v) for k, v in np.load(path).items()}
    rec = generate_sequence(cfg)
    rt, ct = rec.robot_table.to_pydict(), rec.camera_table.to_pydict()
    assert np.allclose(rt["t"], ct["t"]), "stations: robot and camera rows share their times"
    seen = np.array(ct["visible"], dtype=bool)
    sign = np.ones(robot.dof) if robot.q_sign is None else np.asarray(robot.q_sign, dtype=float)
    q = np.array(rt["q_meas"], dtype=float)[seen] * sign
    pq = np.column_stack([ct[f"cam_target_meas_{c}"] for c in ("px", "py", "pz", "qw", "qx", "qy", "qz")])[seen]
    eye_in_hand = cfg.configuration == "eye_in_hand"
    B = inverse(kse3.pq_to_pose(pq)) if eye_in_hand else kse3.pq_to_pose(pq)
    nominal = np.column_stack([robot.a, robot.alpha, robot.d, robot.theta_offset])
    m = rec.manifest
    pose = {name: kse3.pq_to_pose(np.array([m[f"{name}_{c}"] for c in ("px", "py", "pz", "qw", "qx", "qy", "qz")]))
            for name in ("X", "Y")}
    extra = json.loads(m["extra_json"] or "{}")
    true = nominal
    if "true_dh" in extra:
        t = extra["true_dh"]
        true = np.column_stack([t["a"], t["alpha"], t["d"], t["theta_offset"]])
    out = {"A": DHArm.from_table(nominal).forward(q), "B": B, "q": q, "nominal": nominal, "true": true,
           "X": pose["X"], "Y": pose["Y"], "tool": robot.tool_matrix, "robot": cfg.robot,
           "setup": cfg.configuration, "dh": "true_dh" in extra, "level": cfg.level,
           "dh_len_mm": 1e3 * m["dh_len_std_m"], "dh_ang_deg": math.degrees(m["dh_ang_std_rad"])}
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, **out)
    return out


def _x_error(X: np.ndarray, Y: np.ndarray, Xt: np.ndarray, Yt: np.ndarray) -> list[float]:
    """[X rot deg, X mm, Y rot deg, Y mm] of (X, Y) against (Xt, Yt), data in metres."""
    one = {"links": np.eye(4)[None]}
    e = PROBLEM.errors({"X": X, "Y": Y, **one}, {"X": Xt, "Y": Yt, **one})
    return [math.degrees(e["X"]["rotation"]), 1e3 * e["X"]["translation"],
            math.degrees(e["Y"]["rotation"]), 1e3 * e["Y"]["translation"]]


def _offset_errors(sol, nominal: np.ndarray, true: np.ndarray) -> tuple[list[float], list[float]]:
    """The identified joint offsets against KinHEC's truth (deg): |correction - true error| and
    |true error| (what the nominal arm is off by), per identified offset."""
    miss, size = [], []
    for p in sol.diagnostics["kinematics"]["parameters"]:
        joint, kind = p["name"].split()
        if kind != "offset":
            continue
        j = int(joint[1:]) - 1
        truth = true[j, 3] - nominal[j, 3]
        miss.append(math.degrees(abs(p["correction"] - truth)))
        size.append(math.degrees(abs(truth)))
    return miss, size


#: the answers compared on KinHEC: label -> (problem, solver options)
KINHEC_ANSWERS = {"pose-only": ("axyb", {}), "free": ("axyb-kinematic", {"solver": "kinematic-lm", "prior": "none"}),
                  "regularised": ("axyb-kinematic", {"solver": "kinematic-lm"}), "auto": ("axyb-kinematic", {})}


def kinhec_sequence(cfg, cache: Path | None) -> dict | None:
    """Errors of every answer in `KINHEC_ANSWERS` on one KinHEC robot_error sequence, against
    KinHEC's truth (X in its flange frame) and, for the kinematic fits, the 1-sigma they report
    and the identified joint offsets against the truth (None: not standard DH)."""
    d = kinhec_inputs(cfg, cache)
    if d is None:
        return None
    arm = DHArm.from_table(d["nominal"])
    links_seen, X_seen, Y_seen = canonical(d["nominal"], d["true"], d["tool"] @ d["X"], d["Y"])
    oracle = handeye.solve("axyb", A=chain(d["q"], links_seen), B=d["B"])  # the arm's visible errors known
    out = {"id": cfg.sequence_id, "robot": d["robot"], "setup": d["setup"], "dh": bool(d["dh"]), "level": d["level"],
           "stations": len(d["q"]), "oracle": _x_error(inverse(d["tool"]) @ oracle.X, oracle.Y, d["X"], d["Y"])}
    for label, (problem, options) in KINHEC_ANSWERS.items():
        start = time.perf_counter()
        data = {"A": d["A"], "B": d["B"]} if problem == "axyb" else {"A": d["A"], "B": d["B"], "q": d["q"], "dh": arm}
        sol = handeye.solve(problem, **{"solver": "auto", **options}, **data)
        out[label] = _x_error(inverse(d["tool"]) @ sol.X, sol.Y, d["X"], d["Y"])
        out[label + " seconds"] = time.perf_counter() - start
        if problem == "axyb":
            out[label + " vs seen"] = _x_error(sol.X, sol.Y, X_seen, Y_seen)
            out["floor"] = _x_error(inverse(d["tool"]) @ X_seen, Y_seen, d["X"], d["Y"])
            continue
        out[label + " vs seen"] = _x_error(sol.X, sol.Y, X_seen, Y_seen)
        std = sol.diagnostics["std"]
        out[label + " std"] = [math.degrees(std["X"]["rotation"]), 1e3 * std["X"]["translation"],
                               math.degrees(std["Y"]["rotation"]), 1e3 * std["Y"]["translation"]]
        out[label + " answer"] = sol.diagnostics["answer"].split()[0]
        out[label + " offsets"] = _offset_errors(sol, d["nominal"], d["true"])
        if sol.diagnostics.get("prior"):
            out[label + " gamma"] = sol.diagnostics["prior"]["effective_parameters"]
    return out


def _plan(tier: str, limit: int | None) -> list:
    """The tier's robot_error sequences, with `limit`: that many per (robot, setup), drawn at
    random (seed 0) so that both subtracks and the DH error grid's levels appear."""
    from kinhec.plans import build_plan, load_tier

    plan = build_plan(load_tier(tier), ["robot_error"])["robot_error"]
    if not limit:
        return plan
    groups: dict[tuple[str, str], list] = {}
    for cfg in plan:
        groups.setdefault((cfg.robot, cfg.configuration), []).append(cfg)
    rng = np.random.default_rng(0)
    return [g[int(k)] for g in groups.values() for k in sorted(rng.permutation(len(g))[:limit])]


def _print_group(name: str, group: list[dict]) -> None:
    """Medians of one group's errors per answer, the kinematic fits' reported 1-sigma and their
    identified joint offsets against the truth."""
    print(f"\n{name}: {len(group)} sequences of {sorted({r['stations'] for r in group})} stations")
    print(f"  {'answer':24s} {'X rot deg':>9s} {'X mm':>9s} {'Y rot deg':>9s} {'Y mm':>9s}   (medians)")
    for label in [*KINHEC_ANSWERS, "oracle", "floor", "pose-only vs seen",
                  *(f"{a} {k}" for a in ("free", "regularised", "auto") for k in ("vs seen", "std"))]:
        med = np.median([r[label] for r in group], axis=0)
        print(f"  {label:24s} " + " ".join(f"{v:9.4f}" for v in med))
    ratio = np.median([r["regularised"] for r in group], axis=0) / np.median([r["pose-only"] for r in group], axis=0)
    print(f"  {'regularised / pose-only':24s} " + " ".join(f"{v:9.2f}" for v in ratio))
    for label in ("free", "regularised"):
        miss = [x for r in group for x in r[label + " offsets"][0]]
        print(f"  {label} joint offsets vs truth: median {np.median(miss):.4f} deg, p90 {np.percentile(miss, 90):.4f}"
              f" (nominal off by median {np.median([x for r in group for x in r[label + ' offsets'][1]]):.4f})")
    z = np.array([np.array(r["regularised vs seen"]) / np.array(r["regularised std"]) for r in group])
    print(f"  regularised: error / reported 1-sigma vs the visible truth, RMS X {np.sqrt(np.mean(z[:, 0] ** 2)):.2f} / "
          f"{np.sqrt(np.mean(z[:, 1] ** 2)):.2f}, Y {np.sqrt(np.mean(z[:, 2] ** 2)):.2f} / "
          f"{np.sqrt(np.mean(z[:, 3] ** 2)):.2f} (rot / trans; norms over 3 axes: 1 if honest); "
          f"effective parameters median {np.median([r['regularised gamma'] for r in group]):.1f}; auto chose the "
          f"kinematic fit in {sum(r['auto answer'] == 'kinematic' for r in group)}; median solve (ms) "
          + ", ".join(f"{a} {1e3 * np.median([r[a + ' seconds'] for r in group]):.0f}" for a in KINHEC_ANSWERS))


def kinhec(tier: str, limit: int | None, cache: Path | None, out: Path | None) -> None:
    """KinHEC's robot_error track of `tier`, per robot, setup and with or without DH errors."""
    runs = [r for r in (kinhec_sequence(cfg, cache) for cfg in _plan(tier, limit)) if r]
    if out:
        out.write_text(json.dumps(runs))
    print(f"KinHEC {tier} tier, robot_error track: {len(runs)} sequences (errors against KinHEC's truth unless "
          "'vs seen': the truth the data can see, `canonical`)")
    for setup in sorted({r["setup"] for r in runs}):
        for robot in sorted({r["robot"] for r in runs}):
            for dh in (False, True):
                group = [r for r in runs if r["robot"] == robot and r["dh"] == dh and r["setup"] == setup]
                if group:
                    _print_group(f"{setup}, {robot}, {'DH errors' if dh else 'no DH errors'}", group)
        _print_group(f"{setup}, all arms", [r for r in runs if r["setup"] == setup])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--sizes", default="20,50")
    parser.add_argument("--joint-noise", type=float, default=0.005, help="joint reading noise std, deg")
    parser.add_argument("--kinhec", action="store_true", help="KinHEC's robot_error track instead (pip install kinhec)")
    parser.add_argument("--tier", default="small", help="KinHEC tier: small, medium, full")
    parser.add_argument("--limit", type=int, default=None, help="KinHEC: at most this many sequences per arm and setup")
    parser.add_argument("--cache", type=Path, default=Path("/tmp/kinhec/cache"),
                        help="KinHEC: where generated sequences are kept (npz; '' for none)")
    parser.add_argument("--out", type=Path, default=None, help="KinHEC: the per-sequence results as JSON")
    args = parser.parse_args()
    if args.kinhec:
        cache = args.cache / args.tier if str(args.cache) not in ("", ".") else None
        return kinhec(args.tier, args.limit, cache, args.out)
    print(f"axyb-kinematic: {args.trials} trials per size; DH errors on the 17 identifiable parameters, "
          f"joint noise {args.joint_noise:g} deg, camera 0.002 rad / 0.5 mm")
    for m in (int(s) for s in args.sizes.split(",")):
        runs = [trial(m, seed, args.joint_noise) for seed in range(args.trials)]
        print(f"\nm = {m} stations (statuses: {sorted({r['status'] for r in runs})}, "
              f"median solve {1e3 * np.median([r['seconds'] for r in runs]):.0f} ms; auto chose the kinematic fit "
              f"{sum(r['auto answer'] == 'kinematic' for r in runs)} of {len(runs)} times)")
        print(f"  {'':10s} {'X rot deg':>18s} {'X trans mm':>18s} {'Y rot deg':>18s} {'Y trans mm':>18s}   (median / p90)")
        table = {label: np.array([r[label] for r in runs]) for label in ("pose-only", "free", "kinematic", "auto")}
        for label, e in table.items():
            cells = [f"{np.median(e[:, k]):8.4f} / {np.percentile(e[:, k], 90):7.4f}" for k in range(4)]
            print(f"  {label:10s} " + " ".join(f"{c:>18s}" for c in cells))
        ratio = np.median(table["pose-only"], axis=0) / np.median(table["kinematic"], axis=0)
        print(f"  {'ratio':10s} " + " ".join(f"{v:>18.1f}" for v in ratio) + "   (pose-only / kinematic, medians)")
        params = [p for r in runs for p in r["parameters"]]
        for unit, label in (("rad", "angles deg"), ("length", "lengths mm")):
            miss = np.array([p[1] for p in params if p[0] == unit])
            print(f"  DH corrections, {label}: error vs truth median {np.median(miss):.4f}, p90 "
                  f"{np.percentile(miss, 90):.4f}, largest {miss.max():.4f}")
        sig = np.array([p[2] for p in params])
        print(f"  within 2 / 3 sigma of the truth: {np.mean(sig <= 2):.0%} / {np.mean(sig <= 3):.0%} "
              f"(Gaussian: 95% / 99.7%)")


if __name__ == "__main__":
    main()
