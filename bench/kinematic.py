"""Kinematic calibration with hand-eye (``axyb-kinematic``): how much the arm's own DH
errors cost the pose-only answer, and what fitting them gives back.

The study: the simulator's default cell (`AXYBKinematic.simulate`: the LR Mate 200iD-like arm,
the paper's X and Y, eye in hand), true DH = nominal + errors on the 17 identifiable parameters
(joint offsets and twists 0.1-0.5 deg, lengths a, d 0.2-1 mm, random signs), joint readings
with `--joint-noise` deg of noise, camera poses B with 0.002 rad / 0.5 mm per axis (the accuracy
study's camera). Per trial (seed) and number of stations:

- ``pose-only``: axyb's ``auto`` on (A, B), A the controller's nominal forward kinematics;
- ``kinematic``: axyb-kinematic's ``auto`` (``kinematic-lm`` from that start).

Printed per size: median and 90th percentile of the X and Y errors (rotation deg, translation
mm) of both and their ratio; for the kinematic fit the error of the identified DH corrections
against the truth (median and largest over the parameters and trials: deg for angles, mm for
lengths), the share of parameters within 2 and 3 standard deviations of their truth (what the
reported covariance is worth), and the median solve time.

``--kinhec``: the robot_error track of KinHEC's small tier instead (``pip install kinhec``; 24
sequences, made on the fly by `kinhec.generator.generate_sequence`, 0.4 s each): a UR5e and a
KUKA iiwa7 (7 joints), 30 stations, joint noise 1e-4 or 1e-3 rad, half the sequences with DH
errors on every parameter (std 0.1-1 mm and 0.01-0.1 deg, `extra_json.true_dh`). KinHEC's tool
transform (flange <- last DH frame) is constant, so it is folded into X; its q_sign into q. X and
Y errors against KinHEC's truth (which includes what hand-eye data cannot see: the DH errors of
the base and of the last joint) and, for the kinematic fit, against the truth as the data can
see it (`canonical`).

Usage: python bench/kinematic.py [--trials 20] [--sizes 20,50] [--joint-noise 0.005]
       python bench/kinematic.py --kinhec
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.kinematics import LR_MATE_200ID, DHArm
from handeye.geometry.se3 import inverse
from handeye.problems.axyb_kinematic import PROBLEM, canonical, random_errors


def trial(m: int, seed: int, joint_noise_deg: float) -> dict:
    """Errors of the pose-only and the kinematic answer on one simulated cell."""
    table = LR_MATE_200ID.table
    errors = random_errors(table, np.random.default_rng(10_000 + seed))
    noise = NoiseModel({"A": (math.radians(joint_noise_deg), 0.0), "B": (0.002, 0.5)})
    data, truth = PROBLEM.simulate(pairs=m, seed=seed, noise=noise, errors=errors)
    start = time.perf_counter()
    sol = handeye.solve("axyb-kinematic", solver="kinematic-lm", **data)
    seconds = time.perf_counter() - start
    auto = handeye.solve("axyb-kinematic", **data)
    pose = handeye.solve("axyb", A=data["A"], B=data["B"])
    out = {"seconds": seconds, "status": sol.status.value, "auto answer": auto.diagnostics["answer"].split()[0]}
    for label, unknowns in (("pose-only", pose.unknowns), ("kinematic", sol.unknowns), ("auto", auto.unknowns)):
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


def kinhec_sequence(cfg) -> dict | None:
    """Pose-only and kinematic errors on one KinHEC robot_error sequence (None: not standard DH)."""
    from kinhec import se3 as kse3
    from kinhec.generator import generate_sequence
    from kinhec.robots import get_robot

    robot = get_robot(cfg.robot)
    if robot.convention != "standard":
        return None
    rec = generate_sequence(cfg)
    rt, ct = rec.robot_table.to_pydict(), rec.camera_table.to_pydict()
    assert np.allclose(rt["t"], ct["t"]), "stations: robot and camera rows share their times"
    seen = np.array(ct["visible"], dtype=bool)
    sign = np.ones(robot.dof) if robot.q_sign is None else np.asarray(robot.q_sign, dtype=float)
    q = np.array(rt["q_meas"], dtype=float)[seen] * sign
    pq = np.column_stack([ct[f"cam_target_meas_{c}"] for c in ("px", "py", "pz", "qw", "qx", "qy", "qz")])[seen]
    B = inverse(kse3.pq_to_pose(pq))  # eye in hand: T_target_cam
    nominal = np.column_stack([robot.a, robot.alpha, robot.d, robot.theta_offset])
    A = DHArm.from_table(nominal).forward(q)
    m = rec.manifest
    X_true = kse3.pq_to_pose(np.array([m[f"X_{c}"] for c in ("px", "py", "pz", "qw", "qx", "qy", "qz")]))
    Y_true = kse3.pq_to_pose(np.array([m[f"Y_{c}"] for c in ("px", "py", "pz", "qw", "qx", "qy", "qz")]))
    tool = robot.tool_matrix
    extra = json.loads(m["extra_json"] or "{}")
    true = nominal
    if "true_dh" in extra:
        t = extra["true_dh"]
        true = np.column_stack([t["a"], t["alpha"], t["d"], t["theta_offset"]])
    _, X_seen, Y_seen = canonical(nominal, true, tool @ X_true, Y_true)
    sol = handeye.solve("axyb-kinematic", solver="kinematic-lm", A=A, B=B, q=q, dh=DHArm.from_table(nominal))
    auto = handeye.solve("axyb-kinematic", A=A, B=B, q=q, dh=DHArm.from_table(nominal))
    pose = handeye.solve("axyb", A=A, B=B)

    def err(X: np.ndarray, Y: np.ndarray, Xt: np.ndarray, Yt: np.ndarray) -> list[float]:
        e = PROBLEM.errors({"X": X, "Y": Y, "links": np.eye(4)[None]}, {"X": Xt, "Y": Yt, "links": np.eye(4)[None]})
        return [math.degrees(e["X"]["rotation"]), 1e3 * e["X"]["translation"],
                math.degrees(e["Y"]["rotation"]), 1e3 * e["Y"]["translation"]]

    return {"id": cfg.sequence_id, "robot": cfg.robot, "dh": "true_dh" in extra, "stations": len(q),
            "status": sol.status.value, "lr_p": sol.diagnostics["comparison"]["F_p"],
            "auto answer": auto.diagnostics["answer"].split()[0], "auto": err(inverse(tool) @ auto.X, auto.Y, X_true, Y_true),
            "pose-only": err(inverse(tool) @ pose.X, pose.Y, X_true, Y_true),
            "kinematic": err(inverse(tool) @ sol.X, sol.Y, X_true, Y_true),
            "kinematic vs seen": err(sol.X, sol.Y, X_seen, Y_seen), "pose-only vs seen": err(pose.X, pose.Y, X_seen, Y_seen),
            "std": [math.degrees(sol.diagnostics["std"]["X"]["rotation"]), 1e3 * sol.diagnostics["std"]["X"]["translation"],
                    math.degrees(sol.diagnostics["std"]["Y"]["rotation"]), 1e3 * sol.diagnostics["std"]["Y"]["translation"]],
            "weak": any("poorly" in w or "beyond what fitting" in w for w in sol.warnings)}


def kinhec() -> None:
    from kinhec.plans import build_plan, load_tier

    runs = [r for r in map(kinhec_sequence, build_plan(load_tier("small"), ["robot_error"])["robot_error"]) if r]
    print(f"KinHEC small tier, robot_error track: {len(runs)} sequences (errors: X rot deg, X mm, Y rot deg, Y mm; "
          "medians)")
    for robot in sorted({r["robot"] for r in runs}):
        for dh in (False, True):
            group = [r for r in runs if r["robot"] == robot and r["dh"] == dh]
            if not group:
                continue
            print(f"\n{robot}, {'DH errors' if dh else 'no DH errors'}: {len(group)} sequences of "
                  f"{sorted({r['stations'] for r in group})} stations, statuses {sorted({r['status'] for r in group})}")
            for label in ("pose-only", "kinematic", "auto", "pose-only vs seen", "kinematic vs seen", "std"):
                med = np.median([r[label] for r in group], axis=0)
                print(f"  {label:18s} " + "  ".join(f"{v:9.4f}" for v in med))
            print(f"  weak-parameter or no-gain warning in {sum(r['weak'] for r in group)} of {len(group)}; auto chose "
                  f"the kinematic fit in {sum(r['auto answer'] == 'kinematic' for r in group)}; F-test p "
                  "(arm errors seen) " + ", ".join(f"{r['lr_p']:.1g}" for r in group))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--sizes", default="20,50")
    parser.add_argument("--joint-noise", type=float, default=0.005, help="joint reading noise std, deg")
    parser.add_argument("--kinhec", action="store_true", help="KinHEC's robot_error track instead (pip install kinhec)")
    args = parser.parse_args()
    if args.kinhec:
        return kinhec()
    print(f"axyb-kinematic: {args.trials} trials per size; DH errors on the 17 identifiable parameters, "
          f"joint noise {args.joint_noise:g} deg, camera 0.002 rad / 0.5 mm")
    for m in (int(s) for s in args.sizes.split(",")):
        runs = [trial(m, seed, args.joint_noise) for seed in range(args.trials)]
        print(f"\nm = {m} stations (statuses: {sorted({r['status'] for r in runs})}, "
              f"median solve {1e3 * np.median([r['seconds'] for r in runs]):.0f} ms; auto chose the kinematic fit "
              f"{sum(r['auto answer'] == 'kinematic' for r in runs)} of {len(runs)} times)")
        print(f"  {'':10s} {'X rot deg':>18s} {'X trans mm':>18s} {'Y rot deg':>18s} {'Y trans mm':>18s}   (median / p90)")
        table = {label: np.array([r[label] for r in runs]) for label in ("pose-only", "kinematic", "auto")}
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
