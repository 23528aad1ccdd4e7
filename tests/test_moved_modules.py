"""Old module paths (the flat layout, and the modules the layer order moved) still import, as the
same module object, with a DeprecationWarning naming the new path and the removal date; no module
of handeye imports through an old path itself; the layers point down (pyproject's order)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import handeye

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("old, new", [
    ("framework.errors", "base.errors"), ("framework.api", "host.api"), ("framework.registry", "host.registry"),
    ("checks.validation", "geometry.validation"), ("checks.plausibility", "workflow.plausibility"),
    ("streams.resample", "geometry.resample"), ("planning.watch_source", "workflow.watch_source"),
    ("se3", "geometry.se3"), ("errors", "base.errors"), ("self_check", "checks.self_check"),
])
def test_an_old_path_gives_the_module_at_its_new_place_with_a_warning(old, new):
    code = ("import warnings, importlib, sys; warnings.simplefilter('always');"
            f"caught = []; warnings.showwarning = lambda m, c, *a, **k: caught.append((c.__name__, str(m)));"
            f"old = importlib.import_module('handeye.{old}'); new = importlib.import_module('handeye.{new}');"
            "print(old is new); print(caught)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.splitlines()
    assert out[0] == "True"
    assert "DeprecationWarning" in out[1] and f"handeye.{old} is now handeye.{new}" in out[1]
    assert handeye.REMOVAL_DATE in out[1]


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
