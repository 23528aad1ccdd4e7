"""The house: old module paths (the flat layout, and the modules the layer order moved) still
import, as the same module object, with a DeprecationWarning naming the new path and the removal
date; no module of handeye imports through an old path itself; the layers point down (pyproject's
order); the example problem imports only the public face for plugin authors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import handeye

ROOT = Path(__file__).resolve().parents[1]


MOVES = [("framework.errors", "base.errors"), ("framework.api", "host.api"), ("framework.registry", "host.registry"),
         ("checks.validation", "geometry.validation"), ("checks.plausibility", "workflow.plausibility"),
         ("streams.resample", "geometry.resample"), ("planning.watch_source", "workflow.watch_source"),
         ("cli._kinhec_report", "harness.kinhec_report"), ("se3", "geometry.se3"), ("errors", "base.errors"),
         ("self_check", "checks.self_check")]


def test_an_old_path_gives_the_module_at_its_new_place_with_a_warning():
    """Each old path in a fresh interpreter (one for all: a module imports once per process)."""
    code = ("import warnings, importlib, json, sys\n"
            "out = []\n"
            f"for old, new in {MOVES!r}:\n"
            "    with warnings.catch_warnings(record=True) as caught:\n"
            "        warnings.simplefilter('always')\n"
            "        same = importlib.import_module('handeye.' + old) is importlib.import_module('handeye.' + new)\n"
            "    out.append([old, same, [str(w.message) for w in caught if w.category is DeprecationWarning]])\n"
            "print(json.dumps(out))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    for (old, new), (_, same, messages) in zip(MOVES, json.loads(run.stdout)):
        assert same, old
        assert any(f"handeye.{old} is now handeye.{new}" in m and handeye.REMOVAL_DATE in m for m in messages), (old, messages)
    examples = subprocess.run([sys.executable, "-W", "error::DeprecationWarning", "-c",
                               "import handeye.examples, handeye.io.examples as e; assert handeye.examples is e"],
                              capture_output=True, text=True)
    assert examples.returncode == 0, examples.stderr[-400:]  # a public name, not an old path


@pytest.mark.parametrize(("old", "new", "name"), [
    ("handeye.io.pose_readers", "handeye.io.pose_writers", "write_poses"),
    ("handeye.framework.problem", "handeye.framework.problem_cell", "StationReader"),
    ("handeye.framework.problem", "handeye.framework.problem_studies", "BenchSettings"),
    ("handeye.framework.problem", "handeye.framework.problem_engine", "flatten"),
])
def test_a_name_moved_out_of_a_module_is_given_from_its_new_place_with_a_warning(old, new, name):
    import importlib

    with pytest.warns(DeprecationWarning, match=rf"^{old}\.{name} is now {new}\.{name}: .*{handeye.REMOVAL_DATE}"):
        got = getattr(importlib.import_module(old), name)
    assert got is getattr(importlib.import_module(new), name)
    with pytest.raises(ImportError):
        exec(f"from {old} import no_such_name")


def test_no_module_of_handeye_imports_through_an_old_path():
    code = ("import warnings, importlib, pkgutil; warnings.simplefilter('error', DeprecationWarning)\n"
            "for base in ('handeye', 'handeye.problems', 'handeye.plugins'):\n"
            "    package = importlib.import_module(base)\n"
            "    for info in pkgutil.walk_packages(package.__path__, base + '.'):\n"
            "        importlib.import_module(info.name)\n"
            "print('ok')")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.stdout.strip() == "ok", run.stderr[-800:]


def test_the_layers_point_down():
    tool = ROOT.parent / "shared" / "tools" / "layers.py"
    if not tool.exists():
        pytest.skip("../shared/tools/layers.py is not beside this checkout")
    out = subprocess.run([sys.executable, str(tool), str(ROOT)], capture_output=True, text=True).stdout
    assert "0 imports run up, 0 package cycles" in out, out[-800:]
    assert "0 import cycles, 0 plugin-boundary leaks" in out, out[-800:]


def test_the_example_problem_imports_only_the_public_face():
    """docs/plugins.md: a problem plugin needs `handeye` and `handeye.geometry`, nothing internal."""
    import ast

    path = ROOT / "docs" / "examples" / "handeye-example-problem" / "handeye_example_problem.py"
    imported = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            imported.add(node.module)
        elif isinstance(node, ast.Import):
            imported.update(alias.name for alias in node.names)
    handeye_modules = {m for m in imported if m.split(".")[0] == "handeye"}
    assert handeye_modules == {"handeye", "handeye.geometry"}, handeye_modules


def test_the_tests_mirror_the_layers():
    """Each test lives in the folder of the layer it tests (tests/<layer>/, tests/problems/<name>/);
    only the house's own tests (this file, the user-facing text) stay at the top."""
    import tomllib

    layers = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["layers"]["order"])
    problems = {p.name for p in (ROOT / "problems").iterdir() if (p / "__init__.py").is_file()}
    misplaced = []
    for path in (ROOT / "tests").rglob("test_*.py"):
        parts = path.relative_to(ROOT / "tests").parts[:-1]
        if not (parts == () and path.name in ("test_layers.py", "test_user_text.py")
                or len(parts) == 1 and parts[0] in layers
                or len(parts) == 2 and parts[0] == "problems" and parts[1] in problems):
            misplaced.append(str(path.relative_to(ROOT)))
    assert not misplaced, misplaced
