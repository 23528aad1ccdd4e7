"""The live view of a recording (``handeye watch --live``, handeye.planning.live_view): the scene
the figure draws (handeye.planning.scene), served by viser, redrawn at every answer, and a real
headless browser that renders it."""

from __future__ import annotations

import shutil
import socket
import time
import urllib.request

import numpy as np
import pytest

from handeye.planning.scene import cell_scene
from handeye.problems.axyb import PROBLEM
from handeye.vision.boards import parse_board
from handeye.vision.observations import Camera

pytest.importorskip("viser", reason='the live view needs viser (pip install "handeye[live]")')

from handeye.planning.live_view import LiveView  # noqa: E402

BOARD = parse_board("charuco:7x5:30mm:22mm:DICT_4X4_50")
CAMERA = Camera(K=np.array([[900.0, 0, 640], [0, 900.0, 480], [0, 0, 1]]), dist=np.zeros(5), size=(1280, 960))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


@pytest.fixture
def cell():
    data, truth = PROBLEM.simulate(pairs=14, seed=2)
    left_out = np.zeros(14, dtype=bool)
    left_out[10] = True
    return data["A"], truth, left_out


@pytest.fixture
def view():
    live = LiveView("mm", free_port())
    yield live
    live.close()


def test_the_view_draws_the_stations_in_metres_and_follows_the_recording(view, cell):
    A, truth, left_out = cell
    scene = cell_scene(A, truth["X"], truth["Y"], "eye-in-hand", BOARD, CAMERA, left_out, A[:2])
    view.show(scene, "14 stations recorded")
    nodes = view.nodes
    assert {f"/stations/{i + 1}" for i in range(14)} <= set(nodes) and {"/next/1", "/next/2"} <= set(nodes)
    assert {"/base", "/board", "/views", "/cameras"} <= set(nodes)
    np.testing.assert_allclose(nodes["/stations/3"].position, A[2][:3, 3] * 1e-3, atol=1e-12)
    assert type(nodes["/stations/11"]).__name__ == "PointCloudHandle"  # the station left out: a grey point
    # the board's outline: 4 segments at Y, in metres
    np.testing.assert_allclose(nodes["/board"].points[0, 0], scene.board_outline[0] * 1e-3, atol=1e-12)
    html = urllib.request.urlopen(view.url, timeout=10).read()
    assert html.lstrip().lower().startswith(b"<!doctype html>")
    view.show(cell_scene(A[:5], truth["X"], truth["Y"], "eye-in-hand"), "5 stations recorded")
    assert "/stations/6" not in view.nodes and "/next/1" not in view.nodes and "/views" not in view.nodes


def test_watch_live_draws_every_answer_and_says_where(tmp_path, cell, capsys, monkeypatch):
    from test_watch_cli import write_pair

    from handeye.cli import main
    from handeye.planning import live_view

    A, truth, _ = cell
    data, _ = PROBLEM.simulate(pairs=14, seed=2)
    shown = []
    monkeypatch.setattr(live_view.LiveView, "show", lambda self, scene, title: shown.append((len(scene.stations), title)))
    port = free_port()
    assert main(["watch", *write_pair(tmp_path, data["A"], data["B"]), "--once", "--live", str(port)]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0] == f"live view: http://localhost:{port} (open it in a browser)"
    assert shown and shown[-1][0] == 14 and shown[-1][1].startswith("14 stations recorded")


def _browser() -> str | None:
    return next((p for p in map(shutil.which, ("chromium", "chromium-browser", "google-chrome")) if p), None)


def test_a_headless_browser_connects_and_renders_the_cell(view, cell):
    """A real browser (headless Chromium through Playwright) loads the page, connects to the
    scene's websocket and draws it: the screenshot is not a blank page."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="the browser test needs playwright")
    executable = _browser()
    if executable is None:
        pytest.skip("the browser test needs Chromium on the PATH (apt install chromium)")
    A, truth, left_out = cell
    view.show(cell_scene(A, truth["X"], truth["Y"], "eye-in-hand", BOARD, CAMERA, left_out, A[:2]), "14 stations")
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=executable, headless=True,
                                    args=["--use-gl=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox"])
        page = browser.new_page(viewport={"width": 800, "height": 600})
        page.goto(view.url)
        deadline = time.monotonic() + 30
        while not view.server.get_clients() and time.monotonic() < deadline:
            page.wait_for_timeout(200)
        assert view.server.get_clients(), "the page never connected to the scene"
        page.wait_for_timeout(2000)
        shot = page.screenshot()
        browser.close()
    import cv2

    image = cv2.imdecode(np.frombuffer(shot, np.uint8), cv2.IMREAD_COLOR)
    assert image.shape[:2] == (600, 800)
    colours = len(np.unique(image.reshape(-1, 3) // 8, axis=0))
    assert colours > 20, f"the page shows {colours} colours: nothing drawn"
