"""Mutation check: does the test suite catch small, deliberate faults in the solvers and steps?

What it does. A list of realistic bugs (`FAULTS`: a wrong sign, a factor, an off-by-one, a dropped
step, a threshold off by a factor) is applied to the code one at a time, and the test suite is run
against each: first the test files that should catch it (the fault's `targets`, with -x), and, if
those pass, the whole suite (-x) to confirm a miss. Each fault ends as

    caught   a test failed (the first FAILED / ERROR line names it) or a run timed out;
    missed   the targets and the whole suite passed with the fault in place;
    stale    the fault's `old` text is not in its file exactly once (the code moved on: update it);
    error    the fault could not be measured (the mutant does not compile or import, pytest crashed).

Why. Coverage says which lines run, not whether a test would notice if they were wrong. A fault
the suite misses marks a behaviour no test pins down; the report lists those with what they
break, so that a test can be written for them. This is a measurement, not a gate: it is not part
of CI and exits 0 whatever it finds (2 when it cannot set itself up).

It never touches the working tree it is run from. Everything happens in a private copy in the
work directory (default /tmp/handeye-mutants, option --workdir):

    <workdir>/repo      every file `git ls-files` lists, plus untracked files not ignored
                        (`git ls-files --others --exclude-standard`), copied from the repo root
    <workdir>/venv      a fresh venv whose site-packages gets a .pth line pointing to the
                        dependencies of the interpreter running this script, and handeye
                        installed editable from the copy (pip install --no-deps -e)
    <workdir>/logs      pytest's output of every run
    <workdir>/summary.json

Before any fault is applied, the copy's venv must import handeye, its plugins and the modules of
every registered solver from the copy (checked, and refused otherwise), and the whole suite is run
once unmutated (the baseline; --no-baseline skips it): tests that fail there are deselected from
every later run, so that a test broken by someone's work in progress is not counted as a catch.
A mutated file is always restored (also on Ctrl-C or SIGTERM); bytecode is not written, so a
restored file can never be shadowed by its mutant's .pyc.

Usage (from anywhere; the repo is the one this file lives in):

    python tools/mutation_check.py              # every fault (~35 min on 2 cores)
    python tools/mutation_check.py --list       # the faults, and whether each still applies
    python tools/mutation_check.py --only robust-loss-scale nlls-dof
    python tools/mutation_check.py --full       # skip the targets, always the whole suite
    python tools/mutation_check.py --setup-only # build the copy and venv, verify, baseline

Adding a fault: copy a `Fault(...)` entry, give it a unique id, the file (repo-relative), the
exact `old` text (unique in the file; include enough context) and the `new` text, one line saying
what it breaks, and the test files expected to catch it (fast ones first). Keep it a realistic bug
that changes behaviour on some input (not dead code, not only a message) and that still imports.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import hashlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import sysconfig
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Self

REPO = Path(__file__).resolve().parents[1]
DEFAULT_WORKDIR = Path("/tmp/handeye-mutants")
#: marks a directory this tool created (the only kind it deletes)
SENTINEL = ".handeye-mutation-copy"
#: seconds a run of the targets may take (a timeout counts as caught: the fault hangs a test)
TARGET_TIMEOUT = 600.0
#: seconds the whole suite may take at least (else 3x the baseline's time)
SUITE_TIMEOUT_FLOOR = 900.0
PYTEST = ("-m", "pytest", "-q", "-p", "no:cacheprovider")
#: the repo's source folders and the import packages they are installed as (pyproject.toml)
PACKAGE_DIRS = {"core": "handeye", "plugins": "handeye.plugins", "problems": "handeye.problems"}


@dataclasses.dataclass(frozen=True)
class Fault:
    """One deliberate bug: `old` (exactly once in `file`) becomes `new`."""

    id: str
    file: str
    old: str
    new: str
    description: str
    targets: tuple[str, ...]


@dataclasses.dataclass
class Result:
    """What happened to one fault (`verdict`: caught, missed, stale, error)."""

    id: str
    verdict: str
    by: str | None = None  # the first failing test, "timeout", or why stale / error
    phase: str | None = None  # "targets" or "suite": the run that caught it
    seconds: float = 0.0
    file: str = ""
    description: str = ""


@dataclasses.dataclass(frozen=True)
class RunOutcome:
    """One pytest run: its exit code (None: timed out), first failing test, time and log."""

    returncode: int | None
    first_failure: str | None
    seconds: float
    log: Path
    failures: tuple[str, ...] = ()


class SetupError(Exception):
    """The copy, the venv or the baseline cannot be made; the check does not start."""


# ------------------------------------------------------------------------------------- faults
# Targets: the test files expected to catch the fault, fastest first. test_solvers.py is the shared
# suite every solver runs (every problem, solver and backend): slower, so it comes after the
# solver's own file.

FAULTS: tuple[Fault, ...] = (
    # --- the three faults an earlier audit found the suite missed
    Fault("iterative-translations-first-4", "plugins/iterative.py",
          "    tX, tY = solve_translations(data, RX, RY)  # eqs. 20-21",
          "    tX, tY = solve_translations(dataclasses.replace(data, A=data.A[:4], B=data.B[:4]), RX, RY)  # eqs. 20-21",
          "iterative: X's and Y's translations solved from the first 4 pairs only (noisy data: worse translations)",
          ("tests/plugins/test_iterative.py", "tests/plugins/test_solvers.py")),
    Fault("robust-loss-scale", "core/estimation/robust.py",
          "DEFAULT_LOSS_SCALE = 3.5484626592",
          "DEFAULT_LOSS_SCALE = 1.0",
          "robust losses: default loss scale 1.0 instead of sqrt(chi2_6 95%) = 3.55 (inliers down-weighted)",
          ("tests/checks/test_constants.py", "tests/plugins/test_refine.py", "tests/plugins/test_auto.py")),
    Fault("offset-parabola-sign", "core/streams/offset.py",
          "        offset += step * 0.5 * (y0 - y2) / curv",
          "        offset -= step * 0.5 * (y0 - y2) / curv",
          "clock offset: the parabolic refinement of the correlation peak steps the wrong way",
          ("tests/streams/test_streams.py",)),
    # --- solver plugins
    Fault("kron-lstsq-no-sign-choice", "plugins/kron_lstsq/single.py",
          "    (RX, RY), flipped = signed_blocks(system, MX, MY)\n    tX, tY = solve_translations(data, RX, RY)",
          "    (RX, RY), flipped = project_to_so3(np.stack([MX, MY])), False\n    tX, tY = solve_translations(data, RX, RY)",
          "kron-lstsq (axyb): the sign of the rotation blocks no longer chosen by eq. 8's cost (dropped step)",
          ("tests/problems/axyb/test_axyb_problem.py", "tests/plugins/test_solvers.py")),
    Fault("shah-unvec-row-major", "plugins/shah.py",
          '    RX = normalize_rotation(Vt[0].reshape(3, 3, order="F"))',
          "    RX = normalize_rotation(Vt[0].reshape(3, 3))",
          "shah: vec(R_X) unstacked row-major instead of column-major (R_X transposed)",
          ("tests/plugins/test_shah_li.py", "tests/plugins/test_solvers.py")),
    Fault("li-correction-dropped", "plugins/li.py",
          '    return beta + delta, float(sigma[-1]), "seminormal"',
          '    return beta, float(sigma[-1]), "seminormal"',
          "li: the refinement step of the semi-normal equations dropped (normal-equation accuracy only)",
          ("tests/plugins/test_shah_li.py", "tests/plugins/test_solvers.py")),
    Fault("dq-wrong-root", "plugins/dual_quaternion.py",
          "    mu = max(candidates, key=lambda c: float(c @ G @ c))",
          "    mu = min(candidates, key=lambda c: float(c @ G @ c))",
          "dual-quaternion: the root with the smaller real part kept (Daniilidis' rule inverted)",
          ("tests/geometry/test_dual_quaternion.py", "tests/plugins/test_solvers.py")),
    Fault("lmi-sdp-translations-unscaled", "plugins/lmi_sdp/axyb.py",
          "                           MX, MY, tX * scale, tY * scale),",
          "                           MX, MY, tX, tY),",
          "lmi-sdp (axyb): with normalize=True the translations of beta not multiplied back by the scale",
          ("tests/plugins/test_lmi_sdp.py", "tests/plugins/test_solvers.py")),
    Fault("lmi-clarabel-svec-scale", "plugins/lmi_sdp/clarabel.py",
          "        b[self.first_row] = -np.sqrt(2.0) * q",
          "        b[self.first_row] = -q",
          "lmi-sdp clarabel backend: the off-diagonal entries of eq. 14's b not scaled by sqrt 2 (svec)",
          ("tests/plugins/test_lmi_sdp.py", "tests/plugins/test_solvers.py")),
    Fault("lmi-axxb-polish-radius", "plugins/lmi_sdp/axxb.py",
          "        polished = refine_trust_region(P, p, np.sqrt(3.0), r_sdp)",
          "        polished = refine_trust_region(P, p, 3.0, r_sdp)",
          "lmi-sdp (axxb): the Newton polish on |r| = 3 instead of sqrt 3 (radius for squared radius)",
          ("tests/problems/axxb/test_axxb_kronecker.py", "tests/plugins/test_lmi_sdp.py", "tests/plugins/test_solvers.py")),
    Fault("lmi-axbycz-hard-case-axis", "plugins/lmi_sdp/axbycz.py",
          "    k = int(np.argmax(result.w - rho**2))",
          "    k = int(np.argmin(result.w - rho**2))",
          "lmi-sdp (axbycz): in the hard case the missing norm goes along the wrong eigenvector",
          ("tests/problems/axbycz/test_axbycz_linear.py", "tests/plugins/test_solvers.py")),
    Fault("so3-sdp-multipliers-unscaled", "plugins/so3_sdp/single.py",
          "    cert = certificate(M, y, nu * norm, options.redundant)",
          "    cert = certificate(M, y, nu, options.redundant)",
          "so3-sdp: the SDP's multipliers (of M / |M|) not scaled back before the certificate",
          ("tests/plugins/test_so3_sdp.py", "tests/plugins/test_solvers.py")),
    Fault("refine-loss-scale-ignored", "plugins/refine.py",
          "    return nlls.Settings(W, kind, options.loss, float(options.loss_scale), options.estimate,",
          "    return nlls.Settings(W, kind, options.loss, DEFAULT_LOSS_SCALE, options.estimate,",
          "refine/auto: option loss_scale ignored (the default used)",
          ("tests/plugins/test_refine.py", "tests/plugins/test_auto.py")),
    Fault("refine-planar-start-unconstrained", "plugins/refine.py",
          "        if is_planar(data):\n            poses0 = data.planar.constrain(options.UNKNOWNS, poses0)\n",
          "",
          "refine (planar mode): start poses given by the user no longer moved onto the planar constraint",
          ("tests/problems/test_planar.py", "tests/plugins/test_refine.py")),
    Fault("auto-safeguard-inverted", "plugins/auto.py",
          "        if cost_b < cost_a - 1e-12 * abs(cost_a):",
          "        if cost_b > cost_a - 1e-12 * abs(cost_a):",
          "auto: the safeguard keeps the second start's answer when its objective is higher",
          ("tests/plugins/test_auto.py", "tests/problems/axbycz/test_axbycz_methods.py")),
    Fault("auto-outlier-gate-all", "plugins/auto.py",
          "    if not disagreeing and not _beyond(model.residuals(poses), settings.W, model.scale).any():",
          "    if not disagreeing and not _beyond(model.residuals(poses), settings.W, model.scale).all():",
          "auto: the outlier step runs only when every pair is far off (any -> all)",
          ("tests/plugins/test_auto.py", "tests/workflow/test_adversarial.py")),
    Fault("tsai-rodrigues-half", "plugins/classic_handeye.py",
          "    P = 2.0 * data._quaternions[:, 1:]",
          "    P = data._quaternions[:, 1:]",
          "tsai: modified Rodrigues vectors without the factor 2 (OpenCV's motion selection range shifts)",
          ("tests/plugins/test_classic_handeye.py", "tests/plugins/test_solvers.py")),
    Fault("park-transpose", "plugins/classic_handeye.py",
          "    RX = project_to_so3(M.T)",
          "    RX = project_to_so3(M)",
          "park: R_X from M instead of M^T (R_X transposed)",
          ("tests/plugins/test_classic_handeye.py", "tests/plugins/test_solvers.py")),
    Fault("daniilidis-root", "plugins/classic_handeye.py",
          "    k = int(np.argmax(norms))",
          "    k = int(np.argmin(norms))",
          "daniilidis: the root of the smaller |s u1 + u2| kept (OpenCV keeps the larger)",
          ("tests/plugins/test_classic_handeye.py", "tests/plugins/test_solvers.py")),
    Fault("wang-update-side", "plugins/axbycz_wang.py",
          "        R[idx[ok]] = so3_exp(delta[ok].reshape(-1, 3, 3)) @ R[idx[ok]]",
          "        R[idx[ok]] = R[idx[ok]] @ so3_exp(delta[ok].reshape(-1, 3, 3))",
          "wang: the Gauss-Newton step applied on the right of the rotations (linearised on the left)",
          ("tests/problems/axbycz/test_axbycz_methods.py", "tests/plugins/test_solvers.py")),
    Fault("fu-y-not-inverted", "plugins/axbycz_fu.py",
          '    Y = inverse(np.asarray(second.unknowns["Y"], dtype=float))',
          '    Y = np.array(second.unknowns["Y"], dtype=float)',
          "fu-dq: Y taken as step 2's Y instead of its inverse",
          ("tests/problems/axbycz/test_axbycz_methods.py", "tests/plugins/test_solvers.py")),
    Fault("wu-y-z-swapped", "plugins/axbycz_wu.py",
          "    RX, RY, RZ = rotation_from_quat(np.stack([v[:4], U[:, 0], Vt[0]]))",
          "    RX, RY, RZ = rotation_from_quat(np.stack([v[:4], Vt[0], U[:, 0]]))",
          "wu: the rank-one factors of q_Y q_Z^T assigned to Z and Y the wrong way round",
          ("tests/problems/axbycz/test_axbycz_linear.py", "tests/plugins/test_solvers.py")),
    Fault("opencv-chain-order", "plugins/opencv.py",
          "        H[k + 1] = B[k] @ H[k]",
          "        H[k + 1] = H[k] @ B[k]",
          "opencv (axxb): absolute camera poses rebuilt from consecutive motions in the wrong order",
          ("tests/plugins/test_opencv.py", "tests/plugins/test_classic_handeye.py")),
    Fault("reprojection-cx-cy", "plugins/reprojection.py",
          "    K = np.array([[theta[0], camera.K[0, 1], theta[2]], [0.0, theta[1], theta[3]], [0.0, 0.0, 1.0]])",
          "    K = np.array([[theta[0], camera.K[0, 1], theta[3]], [0.0, theta[1], theta[2]], [0.0, 0.0, 1.0]])",
          "reprojection (refine_intrinsics): cx and cy swapped when the refined intrinsics are put back",
          ("tests/plugins/test_reprojection.py",)),
    # --- the least-squares engine and its models
    Fault("axyb-jacobian-sign", "problems/axyb/geometry.py",
          "        J[:, 3:, 9:12] = minus_RY",
          "        J[:, 3:, 9:12] = Y[:3, :3]",
          "refine's A X = Y B model: d t / d v_Y with the wrong sign",
          ("tests/plugins/test_refine.py",)),
    Fault("nlls-profile-gradient", "core/estimation/lm_objective.py",
          "    return a[0] + a[1], profile_hessian(Hw, a, W, m, scale), Hw, F",
          "    return a[0] - a[1], profile_hessian(Hw, a, W, m, scale), Hw, F",
          "nlls: the profile likelihood's gradient subtracts the translation group's part",
          ("tests/plugins/test_refine.py",)),
    Fault("nlls-retraction-left", "core/estimation/nlls.py",
          "    out[:3, :3] = R @ so3_fast.exp(xi[:3])",
          "    out[:3, :3] = so3_fast.exp(xi[:3]) @ R",
          "nlls: the rotation step retracted on the left (the Jacobians are for right perturbations)",
          ("tests/plugins/test_refine.py", "tests/plugins/test_auto.py")),
    Fault("nlls-damping-unscaled", "core/estimation/nlls.py",
          "                step = _newton_step(H + lam * np.diag(Hw.diagonal()), g)",
          "                step = _newton_step(H + lam * np.eye(len(g)), g)",
          "nlls: Levenberg's damping lam * I instead of Marquardt's lam * diag(H) (not unit invariant)",
          ("tests/plugins/test_refine.py", "tests/plugins/test_auto.py", "tests/plugins/test_solvers.py")),
    Fault("nlls-dof", "core/estimation/nlls.py",
          "    dof = 6.0 * float(drho.sum()) - n",
          "    dof = 6.0 * float(drho.sum())",
          "nlls: the variance factor divides by 6m instead of 6m - n (covariance too small by (6m-n)/6m)",
          ("tests/plugins/test_refine.py", "tests/checks/test_self_check.py")),
    Fault("whitening-trans-variance-doubled", "core/estimation/whitening.py",
          "    s_rot, s_trans = math.sqrt(sum_rot / (3 * m)), math.sqrt(sum_trans / (3 * m))",
          "    s_rot, s_trans = math.sqrt(sum_rot / (3 * m)), math.sqrt(2 * sum_trans / (3 * m))",
          "whitening: the estimated translation variance doubled (rotation/translation weights off by 2)",
          ("tests/plugins/test_refine.py", "tests/plugins/test_auto.py")),
    Fault("robust-cauchy-weight", "core/estimation/robust.py",
          "        return c2 * np.log1p(s / c2), 1.0 / (1.0 + s / c2)",
          "        return c2 * np.log1p(s / c2), 1.0 / (1.0 + s / c2) ** 2",
          "robust: Cauchy weight rho'(s) squared (IRLS minimises another loss than the one reported)",
          ("tests/estimation/test_robust.py", "tests/plugins/test_refine.py", "tests/plugins/test_auto.py")),
    Fault("robust-huber-weight", "core/estimation/robust.py",
          "np.where(inlier, 1.0, c / np.maximum(root, c))",
          "np.where(inlier, 1.0, c2 / np.maximum(s, c2))",
          "robust: Huber weight c^2 / s instead of c / sqrt(s) beyond the threshold",
          ("tests/estimation/test_robust.py", "tests/plugins/test_refine.py", "tests/plugins/test_auto.py")),
    # --- SE(3) / SO(3) helpers
    Fault("se3-inverse-sign", "core/geometry/se3.py",
          '    return make_pose(Rt, -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3]))',
          '    return make_pose(Rt, np.einsum("...ij,...j->...i", Rt, T[..., :3, 3]))',
          "se3.inverse: the translation of the inverse without its minus sign",
          ("tests/geometry/test_se3.py",)),
    Fault("se3-project-no-det-fix", "core/geometry/se3.py",
          "    U[..., :, 2] *= d[..., None]\n",
          "",
          "se3.project_to_so3: the det = +1 correction dropped (reflections returned)",
          ("tests/geometry/test_se3.py", "tests/problems/axxb/test_axxb_kronecker.py", "tests/plugins/test_solvers.py")),
    Fault("so3fast-jacobians-swapped", "core/geometry/so3_fast.py",
          "    return common - half, common + half",
          "    return common + half, common - half",
          "so3_fast.inverse_jacobians: left and right inverse Jacobians swapped",
          ("tests/plugins/test_refine.py",)),
    Fault("so3fast-log-angle", "core/geometry/so3_fast.py",
          "    theta = np.arctan2(sin, parts[:, 3] - 0.5)",
          "    theta = np.arctan2(sin, parts[:, 3] - 1.0)",
          "so3_fast.log: cos(theta) taken as tr(R)/2 - 1 instead of (tr(R) - 1)/2",
          ("tests/geometry/test_se3.py", "tests/plugins/test_refine.py")),
    # --- problems
    Fault("axyb-translations-sign", "problems/axyb/data.py",
          '        t = solve(N, np.concatenate([RAt_p, -sum_p]), assume_a="pos")',
          '        t = solve(N, np.concatenate([RAt_p, sum_p]), assume_a="pos")',
          "axyb: eqs. 20-21 (translations given the rotations) with the wrong sign of the t_Y rows",
          ("tests/problems/axyb/test_axyb_problem.py", "tests/plugins/test_solvers.py")),
    Fault("axyb-excitation-threshold", "problems/axyb/data.py",
          "DEGENERATE_EXCITATION = 1e-10",
          "DEGENERATE_EXCITATION = 1e-14",
          "axyb validation: rotation excitation threshold 1e4 times lower (near-degenerate data accepted)",
          ("tests/problems/axyb/test_axyb_problem.py", "tests/base/test_errors.py", "tests/io/test_hostile_input.py")),
    Fault("axyb-min-pairs", "problems/axyb/problem.py",
          "    min_pairs = 3",
          "    min_pairs = 2",
          "axyb validation: 2 pairs accepted (3 needed)",
          ("tests/problems/axyb/test_axyb_problem.py", "tests/base/test_errors.py", "tests/host/test_properties.py")),
    Fault("axxb-translation-rhs-sign", "problems/axxb/data.py",
          "    rhs = sums.sum_tA - sums.RAt_tA - RX @ sums.sum_tB + sums.RAt_R_tB(RX)",
          "    rhs = sums.sum_tA - sums.RAt_tA + RX @ sums.sum_tB + sums.RAt_R_tB(RX)",
          "axxb: the translation of X given R_X with a wrong sign in the right-hand side",
          ("tests/problems/axxb/test_axxb_problem.py", "tests/plugins/test_classic_handeye.py")),
    Fault("axxb-axis-spread-index", "problems/axxb/data.py",
          "        return float(2.0 * np.arctan(np.sqrt(max(lam[1], 0.0) / lam[2])))",
          "        return float(2.0 * np.arctan(np.sqrt(max(lam[0], 0.0) / lam[2])))",
          "axxb validation: axis spread from the smallest eigenvalue (two motions always 'parallel')",
          ("tests/problems/axxb/test_axxb_problem.py", "tests/base/test_errors.py")),
    Fault("axxb-mismatch-sigmas", "problems/axxb/data.py",
          "MISMATCH_SIGMAS = 5.0",
          "MISMATCH_SIGMAS = 50.0",
          "axxb diagnose: mismatched-motion threshold 10x too high (mispaired motions not flagged)",
          ("tests/problems/axxb/test_axxb_problem.py", "tests/base/test_errors.py")),
    Fault("axbycz-translations-sign", "problems/axbycz/kronecker.py",
          '    rhs = tC @ RY.T - tA - np.einsum("iab,ib->ia", RA, tB @ RX.T)',
          '    rhs = tC @ RY.T + tA - np.einsum("iab,ib->ia", RA, tB @ RX.T)',
          "axbycz: translations given the rotations (Wu eq. 38) with the wrong sign of t_A",
          ("tests/problems/axbycz/test_axbycz_linear.py", "tests/problems/axbycz/test_axbycz_problem.py")),
    Fault("axbycz-still-rotation", "problems/axbycz/data.py",
          "STILL_ROTATION = 0.05",
          "STILL_ROTATION = 0.005",
          "axbycz: 'robot holds still' rotation tolerance 10x too small (noisy still phases not found)",
          ("tests/problems/axbycz/test_axbycz_problem.py", "tests/problems/axbycz/test_axbycz_methods.py")),
    # --- the self-check and plausibility
    Fault("selfcheck-distance-fail", "core/checks/self_check.py",
          "DISTANCE_FAIL = 100.0",
          "DISTANCE_FAIL = 1000.0",
          "self-check: an answer fails only beyond 1000 sigma from the best fit (was 100)",
          ("tests/checks/test_self_check.py", "tests/checks/test_constants.py")),
    Fault("selfcheck-residual-factor", "core/checks/self_check.py",
          "ROTATION_RESIDUAL_FACTOR = 10.0",
          "ROTATION_RESIDUAL_FACTOR = 100.0",
          "self-check: check 1 fails only at 100x the expected rotation residual (was 10x)",
          ("tests/checks/test_self_check.py", "tests/checks/test_constants.py")),
    Fault("selfcheck-precision-smallest", "core/checks/self_check.py",
          "        rot_deg = math.degrees(math.sqrt(max(float(w[2 * n, 2]), 0.0)))",
          "        rot_deg = math.degrees(math.sqrt(max(float(w[2 * n, 0]), 0.0)))",
          "self-check precision: rotation 1-sigma from the best-determined direction instead of the worst",
          ("tests/checks/test_self_check.py", "tests/workflow/test_quality_report.py")),
    Fault("selfcheck-majority-boundary", "core/checks/self_check.py",
          "    if share <= MAJORITY:",
          "    if share < MAJORITY:",
          "self-check: exactly half the pairs agreeing counts as a majority (off by one at 50%)",
          ("tests/workflow/test_adversarial.py", "tests/checks/test_self_check.py")),
    Fault("plausibility-explain-factor", "core/workflow/plausibility.py",
          "EXPLAIN_FACTOR = 4.0",
          "EXPLAIN_FACTOR = 40.0",
          "plausibility: a setup mistake explains the data only if it lowers the score 40x (was 4x)",
          ("tests/workflow/test_plausibility.py", "tests/workflow/test_calibrate.py")),
    # --- pose formats, readers, streams
    Fault("pose-format-kuka-extrinsic", "core/io/pose_formats.py",
          '    _preset("kuka-abc", "euler", _angles("a", "b", "c"), seq="ZYX", degrees=True, unit="mm"),',
          '    _preset("kuka-abc", "euler", _angles("a", "b", "c"), seq="zyx", degrees=True, unit="mm"),',
          "pose formats: KUKA A, B, C read as extrinsic zyx instead of intrinsic ZYX",
          ("tests/io/test_pose_readers.py",)),
    Fault("pose-format-quat-order", "core/io/pose_formats.py",
          "        return rot[:, [1, 2, 3, 0]] if self.scalar_first else np.array(rot)",
          "        return rot[:, [3, 0, 1, 2]] if self.scalar_first else np.array(rot)",
          "pose formats: scalar-first quaternions reordered with the inverse permutation",
          ("tests/io/test_pose_readers.py",)),
    Fault("pose-readers-unit-inverted", "core/io/pose_readers.py",
          '        scale = {"mm": 1e-3, "m": 1.0}[self.unit] / {"mm": 1e-3, "m": 1.0}[unit]',
          '        scale = {"mm": 1e-3, "m": 1.0}[unit] / {"mm": 1e-3, "m": 1.0}[self.unit]',
          "pose readers: unit conversion factor inverted (mm -> m multiplies by 1000)",
          ("tests/io/test_pose_readers.py", "tests/workflow/test_calibrate.py")),
    Fault("streams-angular-speed-half", "core/geometry/resample.py",
          "    out[both] = rotation_angle(np.swapaxes(Rb, 1, 2) @ Ra) / (2.0 * half_window)",
          "    out[both] = rotation_angle(np.swapaxes(Rb, 1, 2) @ Ra) / half_window",
          "streams: angular speed twice too high (central difference divided by h, not 2h)",
          ("tests/streams/test_streams.py",)),
    Fault("streams-profile-offset-sign", "core/streams/offset.py",
          "    res = resample_poses(robot_t, robot_T, camera_t + offset, max_gap)",
          "    res = resample_poses(robot_t, robot_T, camera_t - offset, max_gap)",
          "clock offset: the profile cost samples the robot at t - offset (sign convention broken)",
          ("tests/streams/test_streams.py",)),
    # --- vision
    Fault("vision-point-jacobian-sign", "core/vision/projection.py",
          "    dR[:, :, :3] = -G @ skew(P)",
          "    dR[:, :, :3] = G @ skew(P)",
          "vision: d p / d omega_R of the projection chain with the wrong sign",
          ("tests/plugins/test_reprojection.py",)),
    Fault("vision-charuco-origin", "core/vision/boards.py",
          "            xy = np.column_stack([(c + 1) * s, (r + 1) * s])",
          "            xy = np.column_stack([c * s, r * s])",
          "vision: ChArUco corner coordinates one square off (origin at the first inner corner)",
          ("tests/vision/test_vision_boards.py", "tests/workflow/test_calibrate_images.py")),
    # --- file safety
    Fault("output-force-ignored", "core/io/output_files.py",
          "        _commit(part, path, force, flag)",
          "        _commit(part, path, False, flag)",
          "output files: --force ignored (an existing output is never replaced)",
          ("tests/io/test_output_files.py",)),
    Fault("input-yaml-duplicates", "core/io/input_files.py",
          "                first_line[key] = key_node.start_mark.line + 1\n",
          "",
          "input files: YAML keys written twice no longer refused (the first occurrence is not recorded)",
          ("tests/io/test_hostile_input.py",)),
    Fault("npz-member-cap-compressed", "core/io/npz.py",
          "        if info.file_size > MAX_MEMBER_BYTES:",
          "        if info.compress_size > MAX_MEMBER_BYTES:",
          "npz: the member size cap tested on the compressed size instead of the declared uncompressed one",
          ("tests/io/test_hostile_input.py",)),
)


# --------------------------------------------------------------------------------- the copy

def git_files(repo: Path) -> list[str]:
    """Files `git ls-files` lists, and untracked files that are not ignored (repo-relative)."""
    listed: set[str] = set()
    for extra in ((), ("--others", "--exclude-standard")):
        out = subprocess.run(["git", "-C", str(repo), "ls-files", "-z", *extra], check=True,
                             capture_output=True).stdout.decode()
        listed.update(name for name in out.split("\0") if name)
    return sorted(listed)


def git_text(*args: str) -> str:
    """Output of a read-only git command in the repo ("" if git fails); no optional index refresh."""
    return subprocess.run(["git", "--no-optional-locks", "-C", str(REPO), *args], capture_output=True, text=True,
                          check=False).stdout


def check_workdir(workdir: Path, repo: Path) -> None:
    """Refuse a work directory that is the repo, inside it, or contains it."""
    w, r = workdir.resolve(), repo.resolve()
    if w == r or r in w.parents or w in r.parents or w == Path(w.anchor):
        raise SetupError(f"--workdir {w} must lie outside the repository {r} (and not contain it)")


def remove_own_dir(path: Path) -> None:
    """Delete a directory this tool created (it holds SENTINEL); refuse any other."""
    if not path.exists():
        return
    if not (path / SENTINEL).is_file():
        raise SetupError(f"{path} exists and was not made by this tool (no {SENTINEL}); remove it or choose "
                         "another --workdir")
    shutil.rmtree(path)


def build_copy(repo: Path, dest: Path) -> int:
    """A fresh copy of the repo's files (git's list) in `dest`; returns the number copied."""
    remove_own_dir(dest)
    dest.mkdir(parents=True)
    (dest / SENTINEL).write_text("made by tools/mutation_check.py; deleted and rebuilt by it\n")
    copied = 0
    for name in git_files(repo):
        src = repo / name
        if not src.exists() and not src.is_symlink():
            continue  # deleted in the working tree, not yet committed
        target = dest / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, target, follow_symlinks=False)
        copied += 1
    return copied


def child_env(venv: Path) -> dict[str, str]:
    """The environment of every child process: the copy's venv first on PATH, the interpreter
    running this script (whose console scripts run the working tree's handeye) off it, no
    PYTHONPATH, no bytecode written (a restored file must never be shadowed by its mutant's .pyc)."""
    env = dict(os.environ)
    for key in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "PYTHONSAFEPATH", "VIRTUAL_ENV"):
        env.pop(key, None)
    own_bin = str(Path(sys.prefix) / "bin")
    path = [p for p in env.get("PATH", "").split(os.pathsep) if p and p != own_bin]
    env["PATH"] = os.pathsep.join([str(venv / "bin"), *path])
    env["VIRTUAL_ENV"] = str(venv)
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    env["MPLBACKEND"] = "Agg"
    return env


def run_quiet(cmd: Sequence[str], env: dict[str, str], cwd: Path, what: str) -> str:
    """Run a setup command; SetupError with its output when it fails."""
    proc = subprocess.run(list(cmd), env=env, cwd=cwd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise SetupError(f"{what} failed (exit {proc.returncode}):\n{proc.stdout[-3000:]}{proc.stderr[-3000:]}")
    return proc.stdout


def dependency_dirs() -> list[str]:
    """site-packages of the interpreter running this script (its purelib, and platlib if other)."""
    paths = sysconfig.get_paths()
    return list(dict.fromkeys(str(Path(paths[key]).resolve()) for key in ("purelib", "platlib")))


def build_venv(workdir: Path, copy: Path, fresh: bool) -> Path:
    """The copy's venv: created (or reused unless `fresh`), the .pth line to this interpreter's
    dependencies written, handeye installed editable from the copy. Returns its python."""
    venv = workdir / "venv"
    python = venv / "bin" / "python"
    if fresh or not python.exists():
        remove_own_dir(venv)
        run_quiet([sys.executable, "-m", "venv", str(venv)], os.environ.copy(), workdir, "python -m venv")
        (venv / SENTINEL).write_text("made by tools/mutation_check.py\n")
    env = child_env(venv)
    site = run_quiet([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                     env, workdir, "asking the venv for its site-packages").strip()
    Path(site, "handeye_mutation_deps.pth").write_text("".join(f"{d}\n" for d in dependency_dirs()))
    stamp = venv / "installed-from.sha256"
    digest = hashlib.sha256((copy / "pyproject.toml").read_bytes() + str(copy).encode()).hexdigest()
    if fresh or not stamp.exists() or stamp.read_text() != digest:
        print("installing handeye editable from the copy (pip, build isolation) ...", flush=True)
        run_quiet([str(python), "-m", "pip", "install", "--no-deps", "--disable-pip-version-check", "-q",
                   "-e", str(copy)], env, workdir, "pip install --no-deps -e <copy>")
        stamp.write_text(digest)
    return python


#: run in the copy's venv: where handeye, its plugins and every registered solver come from
VERIFY = r"""
import importlib, inspect, json, sys
import handeye
reg = handeye.get_registry()
files = {"handeye": handeye.__file__}
for pkg in ("handeye.plugins", "handeye.problems", "handeye.streams", "handeye.vision"):
    files[pkg] = importlib.import_module(pkg).__file__
solvers = {}
for problem in sorted(reg.problems):
    files["problem " + problem] = inspect.getfile(type(reg.problem(problem)))
    for name in reg.solver_names(problem):
        spec = reg.solver(name, problem)
        solvers[problem + ":" + name] = inspect.getfile(spec.run)
loaded = {m: getattr(mod, "__file__", None) for m, mod in list(sys.modules.items())
          if m == "handeye" or m.startswith("handeye.")}
print(json.dumps({"files": files, "solvers": solvers, "loaded": loaded, "problems": sorted(reg.problems)}))
"""


def verify_copy(python: Path, copy: Path, venv: Path) -> dict:
    """Check that the copy's venv imports handeye (and every registered solver) from the copy."""
    out = run_quiet([str(python), "-c", VERIFY], child_env(venv), copy, "importing handeye in the copy's venv")
    found = json.loads(out.strip().splitlines()[-1])
    every = {**found["files"], **found["solvers"], **{k: v for k, v in found["loaded"].items() if v}}
    outside = {k: v for k, v in every.items() if not Path(v).resolve().is_relative_to(copy.resolve())}
    print(f"handeye.__file__ in the copy's venv: {found['files']['handeye']}", flush=True)
    if outside:
        listing = "\n".join(f"  {k}: {v}" for k, v in sorted(outside.items()))
        raise SetupError(f"the copy's venv imports handeye modules from outside the copy {copy}:\n{listing}\n"
                         "refusing to mutate: the tests would not run the mutated code")
    if not found["solvers"]:
        raise SetupError("the copy's venv imports handeye but its registry has no solvers (entry points not found)")
    print(f"registry loads from the copy: {len(found['problems'])} problems, {len(found['solvers'])} "
          f"(problem, solver) pairs, {len(found['loaded'])} handeye modules, all from the copy", flush=True)
    return found


# ------------------------------------------------------------------------------------ pytest

#: a short-summary line (-ra): "FAILED <node id> - <message>"; node ids may hold spaces
_FAILURE = re.compile(r"^(FAILED|ERROR) (.+?)(?: - .*)?$")


def failures_in(log: Path) -> list[str]:
    """The FAILED / ERROR test ids of a pytest log (short summary, -ra), in order."""
    seen: list[str] = []
    for line in log.read_text(errors="replace").splitlines():
        match = _FAILURE.match(line)
        if match and match.group(2) not in seen:
            seen.append(match.group(2))
    return seen


def run_pytest(python: Path, copy: Path, venv: Path, args: Sequence[str], timeout: float, log: Path) -> RunOutcome:
    """pytest with `args` in the copy, output to `log`; the whole process group is killed on a
    timeout or an interrupt (only processes this call started)."""
    start = time.monotonic()
    with log.open("w") as fh:
        proc = subprocess.Popen([str(python), *PYTEST, *args], cwd=copy, env=child_env(venv),
                                stdout=fh, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            code: int | None = proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            code = None
        finally:
            if proc.poll() is None:
                kill_group(proc)
    found = failures_in(log)
    return RunOutcome(code, found[0] if found else None, time.monotonic() - start, log, tuple(found))


def kill_group(proc: subprocess.Popen) -> None:
    """SIGTERM, then SIGKILL, to the process group of `proc` (started with its own session)."""
    for sig, wait in ((signal.SIGTERM, 10.0), (signal.SIGKILL, 10.0)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(timeout=wait)
            return
        except subprocess.TimeoutExpired:
            continue


def deselect_args(failing: Iterable[str]) -> list[str]:
    return [arg for test in failing for arg in ("--deselect", test)]


# ----------------------------------------------------------------------------------- mutants

def module_of(file: str) -> str | None:
    """The import name of a repo-relative source file (core/streams/offset.py -> handeye.streams.offset)."""
    parts = Path(file).with_suffix("").parts
    package = PACKAGE_DIRS.get(parts[0])
    if package is None or not file.endswith(".py"):
        return None
    rest = [p for p in parts[1:] if p != "__init__"]
    return ".".join([package, *rest])


def occurrences(fault: Fault, copy: Path) -> int:
    path = copy / fault.file
    return path.read_text().count(fault.old) if path.is_file() else 0


def clear_bytecode(path: Path) -> None:
    """Remove cached bytecode of `path` (none should exist: bytecode is not written)."""
    for pyc in (path.parent / "__pycache__").glob(f"{path.stem}.*.pyc"):
        pyc.unlink(missing_ok=True)


class Mutant:
    """Context manager: `fault` applied to the copy, the original restored on exit, whatever happens."""

    def __init__(self, fault: Fault, copy: Path) -> None:
        self.path = copy / fault.file
        self.fault = fault
        self.original: str | None = None

    def __enter__(self) -> Self:
        self.original = self.path.read_text()
        self.path.write_text(self.original.replace(self.fault.old, self.fault.new, 1))
        clear_bytecode(self.path)
        return self

    def __exit__(self, *exc: object) -> None:
        if self.original is not None:
            self.path.write_text(self.original)
            clear_bytecode(self.path)


def import_problem(fault: Fault, python: Path, copy: Path, venv: Path) -> str | None:
    """Why the mutated file does not compile or import (None: it does); faults must not merely
    break imports."""
    source = (copy / fault.file).read_text()
    try:
        compile(source, fault.file, "exec")
    except SyntaxError as exc:
        return f"does not compile: {exc}"
    module = module_of(fault.file)
    if module is None:
        return None
    proc = subprocess.run([str(python), "-c", f"import {module}; import handeye; handeye.get_registry()"],
                          cwd=copy, env=child_env(venv), capture_output=True, text=True, timeout=300, check=False)
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or ["?"])[-1]
        return f"does not import: {last}"
    return None


@dataclasses.dataclass(frozen=True)
class Context:
    """Everything a fault's measurement needs."""

    copy: Path
    venv: Path
    python: Path
    logs: Path
    deselect: tuple[str, ...]
    target_timeout: float
    suite_timeout: float
    full: bool


def judge(run: RunOutcome, phase: str) -> tuple[str, str] | None:
    """(verdict, by) when a run decides the fault (caught or error), None when it passed."""
    if run.returncode is None:
        return "caught", f"timeout after {run.seconds:.0f} s ({phase})"
    if run.returncode == 0:
        return None
    if run.returncode in (1, 2) and run.first_failure:  # 2: interrupted by a collection error
        return "caught", run.first_failure
    if run.returncode == 5 and phase == "targets":  # no tests collected: let the suite decide
        return None
    tail = run.log.read_text(errors="replace").strip().splitlines()[-1:] or ["?"]
    return "error", f"pytest exit {run.returncode} in the {phase} run: {tail[0][:200]} (log {run.log})"


def measure(fault: Fault, ctx: Context) -> Result:
    """Apply `fault`, run its targets, then (if they pass) the whole suite; always restore."""
    start = time.monotonic()
    result = Result(fault.id, "missed", file=fault.file, description=fault.description)
    count = occurrences(fault, ctx.copy)
    if count != 1:
        result.verdict = "stale"
        result.by = f"`old` found {count} times in {fault.file} (must be exactly once)"
        return result
    with Mutant(fault, ctx.copy):
        problem = import_problem(fault, ctx.python, ctx.copy, ctx.venv)
        if problem:
            result.verdict, result.by = "error", f"mutant {problem}"
        else:
            phases = [("suite", (), ctx.suite_timeout)]
            if not ctx.full:
                phases.insert(0, ("targets", fault.targets, ctx.target_timeout))
            for phase, paths, timeout in phases:
                log = ctx.logs / f"{fault.id}.{phase}.log"
                run = run_pytest(ctx.python, ctx.copy, ctx.venv, ["-x", *deselect_args(ctx.deselect), *paths],
                                 timeout, log)
                decided = judge(run, phase)
                if decided:
                    result.verdict, result.by = decided
                    result.phase = phase
                    break
    result.seconds = time.monotonic() - start
    return result


# ---------------------------------------------------------------------------------- reporting

def line(result: Result) -> str:
    by = result.by if result.verdict != "missed" else "missed"
    where = f" [{result.phase}]" if result.phase else ""
    return f"{result.id:<36} {result.verdict:<7} {by}{where}  {result.seconds:6.1f} s"


def summary_text(results: list[Result], total_seconds: float, interrupted: bool) -> str:
    counts = {v: sum(r.verdict == v for r in results) for v in ("caught", "missed", "stale", "error")}
    measured = counts["caught"] + counts["missed"]
    out = ["", "=" * 100,
           (f"mutation check{' (INTERRUPTED)' if interrupted else ''}: {len(results)} faults; caught "
            f"{counts['caught']}/{measured} measured ({counts['caught']}/{len(results)} of all), missed "
            f"{counts['missed']}, stale {counts['stale']}, error {counts['error']}; {total_seconds / 60:.1f} min")]
    for verdict in ("missed", "stale", "error"):
        chosen = [r for r in results if r.verdict == verdict]
        if chosen:
            out.append(f"{verdict}:")
            out += [f"  {r.id} ({r.file}): {r.description}" + (f" -- {r.by}" if verdict != "missed" else "")
                    for r in chosen]
    return "\n".join(out)


def write_summary(path: Path, results: list[Result], meta: dict, total_seconds: float, interrupted: bool) -> None:
    counts = {v: sum(r.verdict == v for r in results) for v in ("caught", "missed", "stale", "error")}
    document = {**meta, "interrupted": interrupted, "total_seconds": round(total_seconds, 1),
                "faults": len(results), "counts": counts,
                "missed": [{"id": r.id, "file": r.file, "description": r.description}
                           for r in results if r.verdict == "missed"],
                "results": [dataclasses.asdict(r) | {"seconds": round(r.seconds, 1)} for r in results]}
    path.write_text(json.dumps(document, indent=2) + "\n")


def list_faults(faults: Sequence[Fault], repo: Path) -> None:
    """Print the faults and whether each applies to the repo's working tree as it is (read only)."""
    for f in faults:
        path = repo / f.file
        count = path.read_text().count(f.old) if path.is_file() else 0
        state = "ok" if count == 1 else f"STALE ({count}x)"
        print(f"{f.id:<36} {state:<11} {f.file}\n    {f.description}\n    targets: {' '.join(f.targets)}")
    print(f"{len(faults)} faults")


# --------------------------------------------------------------------------------------- main

def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--workdir", type=Path, default=DEFAULT_WORKDIR, help="where the copy, venv and logs go")
    parser.add_argument("--only", nargs="+", metavar="ID", help="run only these faults")
    parser.add_argument("--list", action="store_true", help="print the faults (and whether they apply) and exit")
    parser.add_argument("--full", action="store_true", help="skip the targets: always run the whole suite")
    parser.add_argument("--timeout", type=float, default=TARGET_TIMEOUT, help="seconds per run of the targets")
    parser.add_argument("--suite-timeout", type=float, default=None,
                        help=f"seconds per run of the whole suite (default: 3x the baseline, at least {SUITE_TIMEOUT_FLOOR:g})")
    parser.add_argument("--no-baseline", action="store_true", help="do not run the unmutated suite first")
    parser.add_argument("--fresh", action="store_true", help="rebuild the venv too (the copy is always rebuilt)")
    parser.add_argument("--setup-only", action="store_true", help="build, verify and run the baseline, then stop")
    return parser.parse_args(argv)


def chosen_faults(only: Sequence[str] | None) -> list[Fault]:
    ids = [f.id for f in FAULTS]
    duplicates = {i for i in ids if ids.count(i) > 1}
    if duplicates:
        raise SetupError(f"duplicate fault ids: {sorted(duplicates)}")
    if not only:
        return list(FAULTS)
    unknown = [i for i in only if i not in ids]
    if unknown:
        raise SetupError(f"unknown fault id(s) {unknown}; --list shows them")
    return [f for f in FAULTS if f.id in only]


def baseline(ctx: Context) -> tuple[tuple[str, ...], float]:
    """The whole suite, unmutated: (tests failing there, seconds)."""
    print("baseline: the whole suite on the unmutated copy ...", flush=True)
    run = run_pytest(ctx.python, ctx.copy, ctx.venv, [], max(ctx.suite_timeout, 3600.0), ctx.logs / "baseline.log")
    if run.returncode not in (0, 1):
        raise SetupError(f"the unmutated suite does not run cleanly (exit {run.returncode}); see {run.log}")
    print(f"baseline: {'passed' if not run.failures else f'{len(run.failures)} failing test(s), deselected from every run'}"
          f" in {run.seconds:.0f} s", flush=True)
    for test in run.failures:
        print(f"  baseline failure: {test}", flush=True)
    return run.failures, run.seconds


def setup(args: argparse.Namespace) -> tuple[Context, dict]:
    check_workdir(args.workdir, REPO)
    args.workdir.mkdir(parents=True, exist_ok=True)
    copy = args.workdir / "repo"
    copied = build_copy(REPO, copy)
    print(f"copied {copied} files of {REPO} to {copy}", flush=True)
    python = build_venv(args.workdir, copy, args.fresh)
    venv = args.workdir / "venv"
    verify_copy(python, copy, venv)
    logs = args.workdir / "logs"
    remove_own_dir(logs)
    logs.mkdir()
    (logs / SENTINEL).write_text("made by tools/mutation_check.py\n")
    suite_timeout = args.suite_timeout or SUITE_TIMEOUT_FLOOR
    ctx = Context(copy, venv, python, logs, (), args.timeout, suite_timeout, args.full)
    meta = {"repo": str(REPO), "copy": str(copy), "started": datetime.datetime.now().isoformat(timespec="seconds"),
            "head": git_text("rev-parse", "HEAD").strip(), "baseline_failures": [], "baseline_seconds": None,
            "uncommitted_paths": len(git_text("status", "--porcelain").splitlines())}
    if not args.no_baseline:
        failing, seconds = baseline(ctx)
        meta.update(baseline_failures=list(failing), baseline_seconds=round(seconds, 1))
        if args.suite_timeout is None:
            suite_timeout = max(SUITE_TIMEOUT_FLOOR, 3.0 * seconds)
        ctx = dataclasses.replace(ctx, deselect=failing, suite_timeout=suite_timeout)
    meta["suite_timeout"] = ctx.suite_timeout
    meta["target_timeout"] = ctx.target_timeout
    return ctx, meta


def _terminate(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # SIGTERM: stop like Ctrl-C (the mutant is restored on the way out)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        faults = chosen_faults(args.only)
        if args.list:
            list_faults(faults, REPO)
            return 0
        # Ctrl-C and SIGTERM raise KeyboardInterrupt, even where SIGINT was inherited as ignored
        # (a background job of a non-interactive shell): the mutant is restored on the way out
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, _terminate)
        start = time.monotonic()
        ctx, meta = setup(args)
    except SetupError as exc:
        print(f"mutation check: setup failed: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("mutation check: interrupted during setup", file=sys.stderr)
        return 2
    if args.setup_only:
        print(f"setup done in {time.monotonic() - start:.0f} s")
        return 0
    results: list[Result] = []
    interrupted = False
    print(f"{len(faults)} faults; targets first{' (skipped: --full)' if args.full else ''}, then the whole suite "
          f"(timeouts {ctx.target_timeout:.0f} s / {ctx.suite_timeout:.0f} s)", flush=True)
    current: str | None = None  # the fault being measured
    try:
        for fault in faults:
            current = fault.id
            results.append(measure(fault, ctx))
            current = None
            print(line(results[-1]), flush=True)
    except KeyboardInterrupt:
        interrupted = True
        meta["interrupted_during"] = current  # not counted: its measurement did not finish
        print(f"interrupted{f' during {current} (restored, not counted)' if current else ''}", flush=True)
    total = time.monotonic() - start
    print(summary_text(results, total, interrupted), flush=True)
    path = args.workdir / "summary.json"
    write_summary(path, results, meta, total, interrupted)
    print(f"summary written to {path}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
