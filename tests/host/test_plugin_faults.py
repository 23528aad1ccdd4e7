"""Third-party plugins that misbehave: each fault stays the plugin's.

Each case installs a small distribution (module + dist-info with a ``handeye`` entry point, as
an installer writes it) on sys.path and rebuilds the registry:

- a plugin whose ``register_solvers`` raises, or that registers a name a built-in holds
  (``auto``), is skipped with a warning naming it; every other command works;
- a solver that raises its own exception (RuntimeError, KeyError, SystemExit), returns an
  invalid status, a complex or non-SE(3) answer, or a multi-line error, gives a one-line
  `SolverError` naming the plugin (CLI: exit 1, ``handeye: error``, never "internal error");
- a solver that hangs (and swallows the exceptions meant to stop it) is stopped by the time
  limit; a thread it leaves running does not keep the ``handeye`` command alive.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import handeye
from handeye.cli import main
from handeye.host import registry
from handeye.problems.axyb import PROBLEM

DIST = "handeye-faulty-plugin"
MODULE = "handeye_faulty_plugin"

HEADER = """
import time, threading
import numpy as np
import handeye
from handeye import SolverOutput, SolverSpec, hookimpl

def answer(**diagnostics):
    return SolverOutput({"X": np.eye(4), "Y": np.eye(4)}, diagnostics=diagnostics)
"""


def install(site: Path, body: str) -> None:
    """Write `body` (after HEADER) as the module of distribution DIST 0.1.0 with entry point
    ``faulty`` into folder `site`."""
    site.mkdir(exist_ok=True)
    (site / f"{MODULE}.py").write_text(HEADER + textwrap.dedent(body))
    info = site / f"{MODULE}-0.1.0.dist-info"
    info.mkdir(exist_ok=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {DIST}\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text(f"[handeye]\nfaulty = {MODULE}\n")


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """plugin(body): install a faulty plugin and rebuild the registry (undone afterwards)."""
    site = tmp_path / "site"

    def make(body: str) -> handeye.host.registry.Registry:
        install(site, body)
        monkeypatch.syspath_prepend(str(site))
        sys.modules.pop(MODULE, None)
        return registry.reload()

    yield make
    monkeypatch.undo()
    sys.modules.pop(MODULE, None)
    registry.reload()


def one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("handeye: error: "), err
    assert "internal error" not in err
    return err


# ----------------------------------------------------------------------------- registration

@pytest.mark.parametrize("body, why", [
    ("""
     @hookimpl
     def register_solvers(register):
         raise RuntimeError("registration blew up")
     """, "RuntimeError: registration blew up"),
    ("""
     @hookimpl
     def register_solvers(register):
         register(SolverSpec("auto", ("axyb",), lambda data, options, backend: answer()))
     """, "solver 'auto' for problem 'axyb' is registered by both"),
    ("""
     @hookimpl
     def register_problems(register):
         register("not a problem")
     """, "not a handeye.Problem"),
    ("""
     raise SystemExit(0)
     """, "SystemExit"),
], ids=["raises", "takes-auto", "not-a-problem", "exits-on-import"])
def test_a_faulty_registration_skips_only_that_plugin(plugin, capsys, tmp_path, body, why):
    with pytest.warns(handeye.PluginLoadWarning, match=why) as record:
        reg = plugin(body)
    assert DIST in str(record[0].message)
    assert reg.provider("auto", "axyb").distribution == "handeye"
    assert "faulty" in reg.failed and "faulty" not in reg.plugins
    # commands that do not use it work
    assert main(["list"]) == 0
    assert "faulty" in capsys.readouterr().out  # listed among the plugins that failed to load
    assert main(["simulate", "-o", str(tmp_path / "d.npz")]) == 0
    assert main(["solve", "--example"]) == 0
    assert "status optimal" in capsys.readouterr().out


def test_a_plugin_registering_auto_keeps_its_other_solvers_out_too(plugin):
    """Skipped whole: a half-registered plugin would be a surprise."""
    with pytest.warns(handeye.PluginLoadWarning):
        reg = plugin("""
            @hookimpl
            def register_solvers(register):
                register(SolverSpec("faulty-fine", ("axyb",), lambda data, options, backend: answer()))
                register(SolverSpec("auto", ("axyb",), lambda data, options, backend: answer()))
            """)
    assert "faulty-fine" not in reg.solvers


# ----------------------------------------------------------------------------- running

SOLVERS = """
def raises(exc):
    def run(data, options, backend):
        raise exc
    return run

def returning(output):
    return lambda data, options, backend: output

def complex_answer(data, options, backend):
    return SolverOutput({"X": np.eye(4) + 0j, "Y": np.eye(4)})

def last_row(data, options, backend):
    X = np.eye(4)
    X[3] = (0.1, 0.0, 0.0, 1.0)
    return SolverOutput({"X": X, "Y": np.eye(4)})

def stubborn(data, options, backend):
    while True:
        try:
            time.sleep(30)
        except BaseException:
            pass

def spawning(data, options, backend):
    import subprocess, sys
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    with open(options_file(), "w") as fh:
        fh.write(str(child.pid))
    while True:
        time.sleep(30)

def options_file():
    import os
    return os.environ["HANDEYE_TEST_PID_FILE"]

def threaded(data, options, backend):
    threading.Thread(target=time.sleep, args=(3600,)).start()
    return SolverOutput({"X": data.A[0] @ np.linalg.inv(data.A[0]), "Y": np.eye(4)})

@hookimpl
def register_solvers(register):
    for name, run in {
        "f-runtime": raises(RuntimeError("a bug in the plugin")),
        "f-keyerror": raises(KeyError("missing")),
        "f-exit": raises(SystemExit(0)),
        "f-multiline": raises(handeye.SolverError("first line\\nsecond line\\n  third")),
        "f-status": returning(SolverOutput({"X": np.eye(4), "Y": np.eye(4)}, status="great")),
        "f-complex": complex_answer,
        "f-lastrow": last_row,
        "f-hangs": stubborn,
        "f-spawns": spawning,
        "f-thread": threaded,
    }.items():
        register(SolverSpec(name, ("axyb",), run))
"""


@pytest.fixture
def faulty(plugin):
    plugin(SOLVERS)
    data, _ = PROBLEM.simulate(pairs=8, seed=3)
    return data


@pytest.mark.parametrize("solver, message", [
    ("f-runtime", "failed: RuntimeError: a bug in the plugin"),
    ("f-keyerror", "failed: KeyError: 'missing'"),
    ("f-exit", "failed: SystemExit: 0"),
    ("f-multiline", "first line second line third"),
    ("f-status", "returned status 'great', which is not one of optimal"),
    ("f-complex", "returned X with complex entries"),
    ("f-lastrow", "last row [0.1, 0.0, 0.0, 1.0] is not [0, 0, 0, 1]"),
])
def test_a_faulty_solver_is_a_one_line_solver_error(faulty, capsys, solver, message):
    with pytest.raises(handeye.SolverError, match=message.replace("[", r"\[").replace("]", r"\]")) as info:
        handeye.solve("axyb", solver=solver, **faulty)
    assert "\n" not in str(info.value)
    if solver in ("f-runtime", "f-keyerror", "f-exit"):
        assert f"plugin 'faulty', from {DIST} 0.1.0" in str(info.value)
    assert main(["solve", "--example", "--solver", solver]) == 1
    assert message.split(":")[-1].strip() in one_line_error(capsys)


def test_a_solver_that_swallows_every_interruption_is_stopped_by_the_time_limit(faulty, capsys):
    start = time.perf_counter()
    with pytest.raises(handeye.SolverTimeoutError, match=r"solver 'f-hangs' \(plugin 'faulty'.*within 0.5 s"):
        handeye.solve("axyb", solver="f-hangs", time_limit=0.5, **faulty)
    assert time.perf_counter() - start < 5.0
    assert main(["solve", "--example", "--solver", "f-hangs", "--time-limit", "0.5"]) == 1
    assert "gave no answer within 0.5 s" in one_line_error(capsys)


def test_the_time_limit_ends_the_processes_the_solver_started(faulty, tmp_path, monkeypatch):
    """A solver that starts a process of its own and hangs: at the time limit the solver's worker
    and that process end together (one was left running 10 minutes, holding a pipe open)."""
    import os

    pid_file = tmp_path / "pid"
    monkeypatch.setenv("HANDEYE_TEST_PID_FILE", str(pid_file))
    with pytest.raises(handeye.SolverTimeoutError):
        handeye.solve("axyb", solver="f-spawns", time_limit=2.0, **faulty)
    pid = int(pid_file.read_text())
    deadline = time.perf_counter() + 5.0
    while time.perf_counter() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            break
        try:
            os.waitpid(pid, os.WNOHANG)  # reap it, if it is this process's child after all
        except ChildProcessError:
            pass
        time.sleep(0.05)
    else:
        raise AssertionError(f"process {pid} the solver started is still running")


def test_a_third_party_solver_gets_a_time_limit_in_the_cli_by_default(faulty):
    from argparse import Namespace

    from handeye.cli._common import PLUGIN_TIME_LIMIT, time_limit

    assert time_limit(Namespace(time_limit=None), "axyb", "f-hangs") == PLUGIN_TIME_LIMIT
    assert time_limit(Namespace(time_limit=None), "axyb", "auto") is None
    assert time_limit(Namespace(time_limit=0.0), "axyb", "f-hangs") is None
    assert time_limit(Namespace(time_limit=2.0), "axyb", "auto") == 2.0


def test_the_time_limit_changes_no_answer(faulty):
    plain = handeye.solve("axyb", solver="auto", **faulty)
    limited = handeye.solve("axyb", solver="auto", time_limit=30, **faulty)
    np.testing.assert_array_equal(plain.X, limited.X)
    assert plain.status is limited.status is handeye.Status.OPTIMAL


def test_bad_time_limits_are_refused(faulty):
    for bad in (0, -1, float("nan"), float("inf"), True, "5"):
        with pytest.raises(handeye.InputError, match="time_limit must be a number of seconds"):
            handeye.solve("axyb", solver="shah", time_limit=bad, **faulty)


def test_a_thread_left_running_does_not_keep_the_command_alive(tmp_path):
    site = tmp_path / "site"
    install(site, SOLVERS)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", "from handeye.cli import console_main; console_main()",
                           "solve", "--example", "--solver", "f-thread", "--time-limit", "0"],
                          env=env, capture_output=True, text=True, timeout=120)
    assert time.perf_counter() - start < 60
    assert "solver f-thread" in done.stdout and done.returncode in (0, 1), done.stderr


PROBLEM_PLUGIN = """
from handeye.problems.axyb import AXYB

class Broken(AXYB):
    name = "faulty-problem"

    def validate(self, **data):
        raise ZeroDivisionError("validate divides by zero")

    def simulate(self, **kwargs):
        raise IndexError("simulate looks past the end")

@hookimpl
def register_problems(register):
    register(Broken())

@hookimpl
def register_solvers(register):
    register(SolverSpec("faulty-kron", ("faulty-problem",), lambda data, options, backend: answer()))
"""


def test_a_faulty_problem_plugin_is_a_one_line_solver_error(plugin, capsys, tmp_path):
    plugin(PROBLEM_PLUGIN)
    data, _ = PROBLEM.simulate(pairs=8, seed=3)
    with pytest.raises(handeye.SolverError, match=r"problem 'faulty-problem' \(plugin 'faulty', from "
                                                  f"{DIST} 0.1.0\\) failed: ZeroDivisionError"):
        handeye.solve("faulty-problem", solver="faulty-kron", **data)
    assert main(["simulate", "--problem", "faulty-problem", "-o", str(tmp_path / "x.npz")]) == 1
    assert "failed: IndexError: simulate looks past the end" in one_line_error(capsys)


def test_a_study_stops_a_solver_that_swallows_its_time_limit(faulty):
    """`compare --timeout` was defeated by a solver that catches the timeout exception: a third
    party's solver now runs in a worker process that is killed at the limit."""
    from handeye.harness import Spec, Study, Sweep, run_study

    study = Study(name="swallow", problem="axyb", specs=(Spec("f-hangs"), Spec("shah")), trials=2, seed=1,
                  timeout=0.5, sweeps=(Sweep("noise", levels=(1.0,), pairs=(8,)),))
    start = time.perf_counter()
    result = run_study(study, jobs=1, progress=False)
    assert time.perf_counter() - start < 30
    hung = result.select(label="f-hangs")
    assert len(hung) == 2 and all(r["status"] == "failed" and "gave no answer within" in r["error"] for r in hung)
    assert all(r["status"] != "failed" for r in result.select(label="shah"))  # the study went on


def test_a_solver_runs_another_through_the_host(faulty):
    """handeye.run_registered: the one door for one solver to run another (a start), with the
    host's checks and fault wrapping but without the self-check unless asked."""
    data = handeye.get_registry().problem("axyb").validate(**faulty)
    sol = handeye.run_registered("shah", data, problem="axyb")
    assert sol.status is handeye.Status.OPTIMAL and "self_check" not in sol.diagnostics
    assert not sol.X.flags.writeable and sol.X[3].tolist() == [0.0, 0.0, 0.0, 1.0]
    checked = handeye.run_registered("shah", data, problem="axyb", self_check=True)
    assert "self_check" in checked.diagnostics
    np.testing.assert_array_equal(checked.X, sol.X)
    with pytest.raises(handeye.SolverError, match=r"failed: KeyError: 'missing'"):
        handeye.run_registered("f-keyerror", data, problem="axyb")
    with pytest.raises(handeye.SolverError, match="last row"):
        handeye.run_registered("f-lastrow", data, problem="axyb")
    with pytest.raises(handeye.UnknownPluginError, match="unknown option 'nonsense'"):
        handeye.run_registered("shah", data, problem="axyb", options={"nonsense": 1})
