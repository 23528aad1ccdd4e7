"""``--report FILE`` of ``handeye calibrate`` and ``handeye solve``: the quality report
(handeye.workflow.quality_report) written as one self-contained HTML page or as markdown with its PNGs,
on a simulated cell with one corrupted station, and the bad-path exits."""

from __future__ import annotations

import json
import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import handeye
from handeye.cli import main
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse
from handeye.io.pose_writers import write_poses
from handeye.problems.axxb import simulate_stations

#: the corrupted station (0-based pair index; file row BAD + 1)
BAD = 4


def corrupted_cell(tmp_path, stations=12, corrupt=True):
    """A noisy simulated eye-in-hand cell (mm) whose camera pose of station BAD is rotated 3 deg
    (corrupt=False: left as simulated)."""
    st, _ = simulate_stations(stations, seed=3, noise=NoiseModel({"A": (0.001, 0.1), "B": (0.001, 0.1)}))
    camera = np.array(inverse(st["B"]))
    if corrupt:
        camera[BAD, :3, :3] = Rotation.from_euler("x", 3, degrees=True).as_matrix() @ camera[BAD, :3, :3]
    robot = write_poses(tmp_path / "robot.csv", st["A"], "fanuc-wpr", unit="mm")
    cam = write_poses(tmp_path / "camera.csv", camera, "opencv-rvec", unit="mm")
    return robot, cam


def calibrate(robot, camera, *extra):
    return main([str(a) for a in ("calibrate", "--robot", robot, "--robot-format", "fanuc-wpr", "--camera", camera,
                                  "--camera-format", "opencv-rvec", "--camera-unit", "mm", "--setup", "eye-in-hand",
                                  *extra)])


def test_html_report_of_a_corrupted_cell(tmp_path, capsys):
    robot, camera = corrupted_cell(tmp_path)
    report = tmp_path / "report.html"
    code = calibrate(robot, camera, "--report", report)
    out, err = capsys.readouterr()
    assert code == 0, err
    assert f"wrote {report}" in out
    page = report.read_text(encoding="utf-8")
    # self-contained: no external asset, both plots embedded
    assert 'src="http' not in page and "src='http" not in page and "<link" not in page
    images = re.findall(r"src='([^']*)'", page)
    assert len(images) == 2 and all(s.startswith("data:image/png;base64,") for s in images)
    # the answer with frames and uncertainties
    assert "X = T_flange_cam" in page and "Y = T_base_target" in page
    assert len(re.findall(r"1-sigma: rotation [\d.e+-]+ deg, translation [\d.e+-]+ mm", page)) == 2
    # the pair table: one row per station, the corrupted one marked
    rows = re.findall(r"<tr(?: class='outlier')?><td class='l'>(\d+)</td><td class='l'>row (\d+)</td>", page)
    assert [int(k) for k, _ in rows] == list(range(12))
    marked = re.findall(r"<tr class='outlier'><td class='l'>(\d+)</td>", page)
    assert marked == [str(BAD)]
    # diagnostics, warnings with actions, run
    assert "rotation excitation" in page and "plausibility check" in page and "cell size" in page
    assert f"pair {BAD} (file row {BAD + 1}) is far off the others" in page
    assert "check those stations&#x27; images" in page
    assert "record at least" not in page  # 12 stations are enough
    assert "handeye version" in page and "auto (backend" in page and str(robot) in page


def test_markdown_report_writes_pngs_beside_it(tmp_path, capsys):
    robot, camera = corrupted_cell(tmp_path, stations=6, corrupt=False)
    report = tmp_path / "out" / "report.md"
    report.parent.mkdir()
    code = calibrate(robot, camera, "--report", report, "--solver", "kron-lstsq")
    assert code == 0, capsys.readouterr().err
    text = report.read_text(encoding="utf-8")
    for name in ("report_residuals.png", "report_poses.png"):
        png = report.parent / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert f"]({name})" in text
    assert "| 5 | row 6 |" in text
    assert "not reported by solver kron-lstsq" in text
    assert "record at least 10 stations" in text  # 6 stations
    assert "data:" not in text


def test_solve_report_of_an_example(tmp_path, capsys):
    report = tmp_path / "r.htm"
    assert main(["solve", "--example", "--report", str(report), "--json"]) == 0
    _, err = capsys.readouterr()
    assert f"wrote {report}" in err
    page = report.read_text(encoding="utf-8")
    assert "<h2>Residuals per pair</h2>" in page and "class='outlier'" in page  # the example's outliers
    assert page.count("data:image/png;base64,") == 2


@pytest.mark.parametrize("name, message", [("report.pdf", "unknown extension '.pdf'"),
                                           ("missing/report.html", "does not exist")])
def test_bad_report_path(tmp_path, capsys, name, message):
    robot, camera = corrupted_cell(tmp_path, stations=6)
    code = calibrate(robot, camera, "--report", tmp_path / name)
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert message in err and len(err.strip().splitlines()) == 1
    assert main(["solve", "--example", "--report", str(tmp_path / name)]) == 2
    assert message in capsys.readouterr().err


def test_report_never_imported_by_a_solve():
    import subprocess
    import sys

    code = ("import sys, handeye; d, t, m = handeye.examples.load_example('simulated'); "
            "handeye.solve('axyb', A=d['A'], B=d['B'], solver='kron-lstsq'); "
            "assert 'matplotlib' not in sys.modules and 'handeye.workflow.quality_report' not in sys.modules")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, done.stderr


def test_advice_reads_the_precision_warnings():
    """The self-check's precision warnings become the report's advice (which axis to add)."""
    from handeye.workflow.quality_report import advice

    base = {"status": "optimal", "problem": "axyb", "item": "station", "unit": "mm", "warnings": [], "std": {},
            "residuals": {"rotation_deg": [0.1] * 12},
            "outliers": [], "stations": 12}
    one_axis = {**base, "warnings": ["the data determine the translation of X only to 9 in their length unit (1-sigma, "
                                     "along (+0.00, +0.00, +1.00), the robot's main rotation axis in ...)"]}
    found = [row[0] for row in advice(one_axis)]
    assert any("mostly about one axis" in f for f in found)
    noisy = {**base, "warnings": ["the data determine the rotation of X only to 0.5 deg (1-sigma, about ...)"]}
    assert any("poorly at their noise" in row[0] for row in advice(noisy))
    assert not any("poorly" in row[0] for row in advice(base))


# ----------------------------------------------------------------------------- the report of an image run

class _Tables(HTMLParser):
    """The tables of an HTML page: [(header cells or None, [row cells, ...]), ...]; and the images."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: list[tuple[list[str] | None, list[list[str]]]] = []
        self.images: list[str] = []
        self._row: list[str] | None = None
        self._cell: list[str] | None = None
        self._header = False

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append((None, []))
        elif tag == "tr":
            self._row, self._header = [], False
        elif tag in ("td", "th"):
            self._cell = []
            self._header = tag == "th"
        elif tag == "img":
            self.images.append(dict(attrs)["src"])

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append("".join(self._cell).strip())
            self._cell = None
        elif tag == "tr" and self._row is not None:
            head, rows = self.tables[-1]
            if self._header:
                self.tables[-1] = (self._row, rows)
            else:
                rows.append(self._row)
            self._row = None


def test_the_report_of_an_image_run(tmp_path, capsys):
    """The bundled real circle-grid set: the report shows the board, the intrinsics with their
    calibration RMS, every image's reprojection error (its own pose and predicted through the
    robot), overlays of the 3 worst images, the full command line, the data as given beside the
    setup mistakes tried, and every warning of the run with what to do; no table has an empty
    column or an empty header row."""
    data = Path(handeye.__file__).parent / "data" / "rct_circle_grid"
    report = tmp_path / "run.html"
    argv = ["calibrate", "--images", str(data / "images"), "--board", "circlegrid:10x10:25.4mm", "--robot",
            str(data / "poses"), "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m", "--setup", "eye-in-hand",
            "--report", str(report), "--json"]
    assert main(argv) == 0
    result = json.loads(capsys.readouterr().out)
    page = _Tables()
    page.feed(report.read_text(encoding="utf-8"))
    assert len(page.images) == 5 and all(s.startswith("data:image/png;base64,") for s in page.images)
    cells = {row[0]: row[1:] for _, rows in page.tables for row in rows if row}
    assert cells["board"] == ["circlegrid:10x10:25.4mm"] and cells["intrinsics"] == ["calibrated from the images"]
    assert cells["calibration RMS [px]"] == [f"{result['camera']['rms_px']:.3g} over 15 images"]
    per_image = next(rows for head, rows in page.tables if head and head[0] == "image")
    assert [r[0] for r in per_image] == [str(k) for k in range(15)]
    own = [float(r[3]) for r in per_image]
    predicted = [float(r[4]) for r in per_image]
    expected = [s["rms_px"] for s in result["images"]["stations"]]
    np.testing.assert_allclose(own, expected, rtol=5e-3)  # the corners' own fit, as the run printed it
    assert min(p / o for p, o in zip(predicted, own)) > 3  # this arm's pose errors: several px through it
    assert "handeye calibrate --images" in cells["command"][0] and "--board circlegrid:10x10:25.4mm" in cells["command"][0]
    hypotheses = next(rows for head, rows in page.tables if head and head[0] == "hypothesis")
    assert hypotheses[0][0] == "the data as given" and float(hypotheses[0][3]) < 1
    advice_rows = next(rows for head, rows in page.tables if head == ["found", "what to do"])
    text = " ".join(" ".join(r) for r in advice_rows)
    for warning in result["warnings"]:
        first = warning.split(":")[0] if not warning.startswith("the data determine") else "poorly at their noise"
        assert first in text, warning
    assert "camera_scale=" not in text and "--camera-scale unknown" in text  # the command line's words
    for head, rows in page.tables:
        assert head is None or any(head), head  # no empty header row
        width = max(len(r) for r in rows)
        for k in range(width):
            assert any(k < len(r) and r[k] for r in rows), (head, k)  # no empty column
