"""Stopping and resuming studies: the journal, SIGINT / SIGTERM / SIGKILL, workers that die with
their parent, and reports written whole or not at all (docs/harness.md, "Interruptions, the
journal and resuming").

The signal tests run ``handeye compare`` in a subprocess with a run-time solver that sleeps
(`SLEEP` s per solve), so that the run is at a known pace whatever the machine: the test waits
until the journal holds a few units, signals, and checks what is on disk and which processes are
left; then it reruns the command and compares the final CSV with an uninterrupted run's.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from handeye.base.errors import InputError
from handeye.estimation.noise import NoiseModel
from handeye.harness import (
    Spec,
    Study,
    Sweep,
    load_study,
    read_csv,
    run_study,
    write_report,
)
from handeye.harness.result import JOURNAL_SUFFIX, StudyJournal

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals and /proc: Linux")

#: seconds the slow solver sleeps per solve: 40 units of 2 jobs take >= 1 s, so a run is still
#: going when the test signals it after a few units
SLEEP = 0.05
UNITS = 40
#: ``handeye compare`` with a run-time solver ``interrupt-test-slow`` (sleeps $INTERRUPT_TEST_SLEEP
#: s, touches $INTERRUPT_TEST_MARK, answers the identity: deterministic rows)
SCRIPT = textwrap.dedent("""
    import os, sys, time
    import numpy as np
    from handeye import SolverOutput, SolverSpec, hookimpl
    from handeye.host.registry import register_plugin

    def slow(data, options, backend):
        if os.environ.get("INTERRUPT_TEST_MARK"):
            open(os.environ["INTERRUPT_TEST_MARK"], "a").close()
        time.sleep(float(os.environ.get("INTERRUPT_TEST_SLEEP", "0")))
        return SolverOutput(unknowns={"X": np.eye(4), "Y": np.eye(4)})

    class Plugin:
        @hookimpl
        def register_solvers(self, register):
            register(SolverSpec(name="interrupt-test-slow", problems=("axyb",), run=slow, summary="sleeps"))

    register_plugin(Plugin(), "interrupt-test-plugin")
    from handeye.cli import main
    sys.exit(main(sys.argv[1:]))
""")


def compare_args(outdir: Path, jobs: int) -> list[str]:
    """A study of 2 levels x 1 pair count x 20 trials = `UNITS` units, 2 solvers."""
    return ["compare", "--solvers", "kron-lstsq,interrupt-test-slow", "--noise-levels", "0,0.01", "--pairs", "8",
            "--trials", "20", "--name", "tiny", "--jobs", str(jobs), "--no-progress", "-o", str(outdir)]


def start(args: list[str], log: Path, sleep: float = SLEEP, **env: str) -> subprocess.Popen[bytes]:
    """The script in a subprocess, stdout and stderr to files (no pipe a survivor could hold)."""
    environment = {**os.environ, "INTERRUPT_TEST_SLEEP": str(sleep), **env}
    with log.with_suffix(".out").open("wb") as out, log.with_suffix(".err").open("wb") as err:
        return subprocess.Popen([sys.executable, "-c", SCRIPT, *args], stdout=out, stderr=err, env=environment)


def finish(process: subprocess.Popen[bytes], log: Path, timeout: float = 60) -> tuple[int, str, str]:
    code = process.wait(timeout)
    return code, log.with_suffix(".out").read_text(), log.with_suffix(".err").read_text()


def journal_units(path: Path) -> list[dict]:
    """The unit lines of a journal (whole lines only)."""
    text = path.read_text() if path.exists() else ""
    lines = text.split("\n")[:-1]
    return [json.loads(line) for line in lines[1:]]


def wait_for_units(path: Path, count: int, process: subprocess.Popen[bytes], log: Path) -> None:
    deadline = time.monotonic() + 30
    while len(journal_units(path)) < count:
        if process.poll() is not None:
            pytest.fail(f"the study ended (code {process.returncode}) before {count} units were journaled: "
                        f"{log.with_suffix('.err').read_text()}")
        assert time.monotonic() < deadline, "no journal rows after 30 s"
        time.sleep(0.01)


def descendants(pid: int) -> set[int]:
    """Every process below `pid` (from /proc: children of each of its threads)."""
    found: set[int] = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            children = (task / "children").read_text().split()
        except OSError:
            continue
        for child in map(int, children):
            found |= {child} | descendants(child)
    return found


def alive(pid: int) -> bool:
    """Running (a zombie waiting for its reaper is not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def survivors(pids: set[int], within: float) -> set[int]:
    """The processes of `pids` still running after `within` s; those are then killed, so that a
    failing test leaves none behind."""
    deadline = time.monotonic() + within
    while (left := {p for p in pids if alive(p)}) and time.monotonic() < deadline:
        time.sleep(0.02)
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    return left


def without_times(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return [{k: v for k, v in row.items() if k != "seconds"} for row in rows]


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory: pytest.TempPathFactory) -> list[dict[str, str]]:
    """The rows of the study run in one go (no sleep: the rows do not depend on it)."""
    outdir = tmp_path_factory.mktemp("uninterrupted")
    code, _out, err = finish(start(compare_args(outdir, 2), outdir / "log", sleep=0), outdir / "log")
    assert code == 0, err
    assert not (outdir / f"tiny{JOURNAL_SUFFIX}").exists()  # removed once the outputs are written
    rows = read_csv(outdir / "tiny.csv")
    assert len(rows) == 2 * UNITS
    return rows


@pytest.mark.parametrize(("signame", "jobs", "code"), [("SIGINT", 2, 130), ("SIGTERM", 2, 143), ("SIGTERM", 1, 143),
                                                       ("SIGKILL", 2, -9)])
def test_a_signalled_study_keeps_its_rows_stops_its_workers_and_resumes(tmp_path, uninterrupted, signame, jobs, code):
    journal = tmp_path / f"tiny{JOURNAL_SUFFIX}"
    log = tmp_path / "first"
    process = start(compare_args(tmp_path, jobs), log)
    wait_for_units(journal, 3, process, log)
    processes = descendants(process.pid) | {u["pid"] for u in journal_units(journal)} - {process.pid}
    assert len(processes) >= (jobs if jobs > 1 else 0)
    process.send_signal(getattr(signal, signame))
    got, out, err = finish(process, log)
    assert got == code, err
    # no worker is left: stopped by the parent (SIGINT, SIGTERM), or by the kernel when the
    # parent was killed (PR_SET_PDEATHSIG)
    assert not survivors(processes, within=0.5 if signame != "SIGKILL" else 5.0)
    saved = journal_units(journal)
    assert 3 <= len(saved) < UNITS
    assert all(len(u["records"]) == 2 for u in saved)
    assert not (tmp_path / "tiny.csv").exists()
    if signame != "SIGKILL":
        assert "Traceback" not in err
        assert err.strip().splitlines()[-1] == (
            f"handeye: stopped by {signame}: {len(saved)} of {UNITS} trials saved in {journal}; "
            "run the same command again to resume")

    log = tmp_path / "second"
    got, out, err = finish(start(compare_args(tmp_path, jobs), log, sleep=0), log)
    assert got == 0, err
    assert out.startswith(f"resumed {len(saved)} of {UNITS} trials from {journal}\n")
    assert without_times(read_csv(tmp_path / "tiny.csv")) == without_times(uninterrupted)
    assert not journal.exists()


def tiny_study_file(path: Path, seed: int = 0) -> Path:
    path.write_text(textwrap.dedent(f"""
        name = "toml"
        trials = 2
        seed = {seed}
        warmup = false
        levels = [0.0, 1.0]
        pairs = [8]
        [noise]
        B = [0.005, 0.5]
        [[solver]]
        name = "kron-lstsq"
    """))
    return path


def test_resume_drops_a_torn_line_and_a_journal_of_another_study_is_refused(tmp_path, capsys):
    from handeye.cli import main

    study_file = tiny_study_file(tmp_path / "study.toml")
    outdir = tmp_path / "out"
    journal = outdir / f"toml{JOURNAL_SUFFIX}"
    whole = run_study(load_study(study_file), jobs=1, progress=False, journal=journal)
    assert whole.resumed == 0 and journal.exists()  # from Python the journal stays
    lines = journal.read_text().splitlines(keepends=True)
    assert len(lines) == 1 + 4
    journal.write_text("".join(lines[:3]) + lines[3][:25])  # 2 whole units, then a write cut short

    args = ["compare", "--study", str(study_file), "--jobs", "1", "--no-progress", "-o", str(outdir)]
    before = journal.read_bytes()
    assert main([*args, "--seed", "5"]) == 2  # another definition: refused, nothing touched
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "another definition of study 'toml'" in err and "--force" in err
    assert journal.read_bytes() == before

    assert main(args) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"resumed 2 of 4 trials from {journal}\n")
    rows = read_csv(outdir / "toml.csv")
    assert [(r["level"], r["trial"]) for r in rows] == [("0.0", "0"), ("0.0", "1"), ("1.0", "0"), ("1.0", "1")]
    assert without_times(rows) == without_times(read_csv(whole.to_csv(tmp_path / "whole.csv")))
    assert not journal.exists()

    assert main(args) == 2  # finished results are not overwritten without --force
    assert "already holds 'toml.csv'" in capsys.readouterr().err
    assert main([*args, "--force"]) == 0
    assert "resumed" not in capsys.readouterr().out


def test_journal_identity_is_the_study_fingerprint(tmp_path):
    study = Study(name="fp", specs=(Spec("kron-lstsq"),), noise=NoiseModel({"B": (0.005, 0.5)}),
                  sweeps=(Sweep("noise", levels=(0.0, 1.0), pairs=(8,)),), trials=2, warmup=False)
    assert study.fingerprint() == study.replace(level_label="sigma", center="mean").fingerprint()  # figures only
    for change in ({"trials": 3}, {"seed": 1}, {"timeout": 5.0}, {"specs": (Spec("shah"),)},
                   {"sweeps": (Sweep("noise", levels=(0.0, 2.0), pairs=(8,)),)}):
        assert study.replace(**change).fingerprint() != study.fingerprint(), change
    path = tmp_path / "fp.journal.jsonl"
    run_study(study, jobs=1, progress=False, journal=path)
    assert StudyJournal.open(path, study).resumed == 4
    with pytest.raises(InputError, match="another definition of study 'fp'.*fresh=True"):
        StudyJournal.open(path, study.replace(trials=3))
    assert StudyJournal.open(path, study, fresh=True).resumed == 0 and not path.exists()
    path.write_text("trial,label\n0,kron-lstsq\n")
    with pytest.raises(InputError, match="is not a journal of a handeye study"):
        StudyJournal.open(path, study)


def test_reports_are_written_whole_or_not_at_all(tmp_path, monkeypatch):
    from handeye.harness import report

    study = Study(name="whole", specs=(Spec("kron-lstsq"),), sweeps=(Sweep("noise", levels=(0.0, 1.0), pairs=(8,)),),
                  trials=1, warmup=False)
    result = run_study(study, jobs=1, progress=False)

    def broken_plot(result, outdir, **kwargs):
        (Path(outdir) / "whole_noise_vs_noise_m8.png").write_bytes(b"\x89PNG half")
        raise KeyboardInterrupt  # as Ctrl-C while the figures are drawn

    monkeypatch.setattr(report, "plot_study", broken_plot)
    with pytest.raises(KeyboardInterrupt):
        write_report(result, tmp_path)
    assert list(tmp_path.iterdir()) == []  # no CSV, no half figure, no staging folder
    monkeypatch.undo()
    paths = write_report(result, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [paths[k].name for k in ("csv", "json", "times", "errors")] + [p.name for p in paths["figures"]])
    assert len(read_csv(paths["csv"])) == 2


def test_a_signalled_cross_validation_leaves_no_file(tmp_path):
    outdir, mark, log = tmp_path / "cv", tmp_path / "solving", tmp_path / "cv-log"
    process = start(["compare", "--example", "eth-robot-arm", "--folds", "3", "--solvers",
                     "kron-lstsq,interrupt-test-slow", "--no-progress", "-o", str(outdir)], log, sleep=0.5,
                    INTERRUPT_TEST_MARK=str(mark))
    deadline = time.monotonic() + 30
    while not mark.exists():
        assert process.poll() is None and time.monotonic() < deadline, log.with_suffix(".err").read_text()
        time.sleep(0.01)
    process.send_signal(signal.SIGTERM)
    code, _out, err = finish(process, log)
    assert code == 143, err
    assert err.strip().splitlines()[-1] == (f"handeye: stopped by SIGTERM before the cross-validation was written "
                                            f"(nothing of it is in {outdir}); run the command again")
    assert not outdir.exists() or list(outdir.iterdir()) == []


def test_a_worker_without_prctl_notices_its_parent_died(tmp_path):
    """The fallback of `handeye.framework.processes.die_with_parent` where PR_SET_PDEATHSIG is not available: a thread
    that watches os.getppid()."""
    middle = textwrap.dedent("""
        import os, sys, time
        from handeye.framework import processes
        parent = os.getpid()
        child = os.fork()
        if child == 0:
            processes.set_parent_death_signal = lambda signum: False  # as on macOS
            processes.die_with_parent(parent, poll=0.05)
            time.sleep(60)
            os._exit(0)
        print(child, flush=True)
        time.sleep(60)
    """)
    process = subprocess.Popen([sys.executable, "-c", middle], stdout=subprocess.PIPE, text=True)
    try:
        child = int(process.stdout.readline())
        time.sleep(0.3)
        assert alive(child)  # the watch does not end a worker whose parent lives
        process.kill()
        process.wait(10)
        assert not survivors({child}, within=3.0)
    finally:
        process.kill()
        process.stdout.close()


def test_journal_lines_are_whole_units_with_their_keys(tmp_path):
    study = Study(name="lines", specs=(Spec("kron-lstsq"), Spec("shah")), sweeps=(Sweep("s", levels=(0.0,), pairs=(8, 9)),),
                  trials=2, warmup=False)
    path = tmp_path / "lines.journal.jsonl"
    result = run_study(study, jobs=2, progress=False, journal=path)
    header, *units = [json.loads(line) for line in path.read_text().splitlines()]
    assert header["format"] == "handeye-study-journal" and header["units"] == 4
    assert header["fingerprint"] == study.fingerprint()
    assert sorted(u["unit"] for u in units) == [["s", 0, 0, 0], ["s", 0, 0, 1], ["s", 0, 1, 0], ["s", 0, 1, 1]]
    assert all(u["pid"] != os.getpid() for u in units)  # run by the workers
    by_key = {tuple(u["unit"]): u["records"] for u in units}
    assert [r for key in sorted(by_key) for r in by_key[key]] == _sorted_records(result.records)
    # the records survive JSON with their types: the CSV of a resumed run is the same text
    again = run_study(study, jobs=1, progress=False, journal=path)
    assert again.resumed == 4 and again.records == result.records
    assert result.to_csv(tmp_path / "a.csv").read_text() == again.to_csv(tmp_path / "b.csv").read_text()
    with (tmp_path / "a.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 8


def _sorted_records(records: list[dict]) -> list[dict]:
    """Records in unit-key order (pairs index = the order of m here)."""
    return sorted(records, key=lambda r: (r["pairs"], r["trial"]))


@pytest.mark.parametrize("damage", ["no records", "records not a list", "a record short", "a record of no solver",
                                    "a record without status"])
def test_a_journal_line_with_damaged_records_is_refused_before_any_work(tmp_path, capsys, damage):
    """A unit's line whose records are not one whole record per solver (none at all: the trial
    would silently vanish from the CSV; damaged ones: an internal error after redoing every other
    unit) is a damaged journal: exit 2 naming the line, nothing recomputed or touched."""
    from handeye.cli import main

    study_file = tiny_study_file(tmp_path / "study.toml")
    outdir = tmp_path / "out"
    journal = outdir / f"toml{JOURNAL_SUFFIX}"
    run_study(load_study(study_file), jobs=1, progress=False, journal=journal)
    header, first, *rest = journal.read_text().splitlines()
    entry = json.loads(first)
    record = entry["records"][0]
    entry["records"] = {"no records": [], "records not a list": "x", "a record short": [record, record],
                        "a record of no solver": [{**record, "label": "other"}],
                        "a record without status": [{k: v for k, v in record.items() if k != "status"}]}[damage]
    journal.write_text("\n".join([header, json.dumps(entry), *rest]) + "\n")
    before = journal.read_bytes()
    args = ["compare", "--study", str(study_file), "--jobs", "1", "--no-progress", "-o", str(outdir)]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "line 2 is damaged" in err and "--force" in err, err
    assert journal.read_bytes() == before and not (outdir / "toml.csv").exists()
