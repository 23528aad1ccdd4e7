"""The fast image path (handeye.vision.detection_pool, detection_cache, detection_plan): detections
on several threads are those of the serial path to the last bit and in the images' order; a cache
hit gives the same detections as detecting, and a changed image or board misses; damaged entries
are ignored; the chessboard flag-set plan keeps the corners the full run keeps; the camera is
calibrated once per image set; SB searched in a crop around the board finds the full image's
corners to hundredths of a pixel, and the full image when the crop fails."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from handeye.io.examples import image_example_dir
from handeye.vision import detection_cache, detection_plan, detection_pool
from handeye.vision import image_set as image_set_module
from handeye.vision.best_corners import choose
from handeye.vision.boards import parse_board
from handeye.vision.detection_cache import DetectionCache
from handeye.vision.image_detection import Outcome
from handeye.vision.image_set import images_and_poses, list_images
from handeye.vision.observations import Camera
from handeye.vision.render import render, view_pose

CIRCLES = "circlegrid:10x10:25.4mm"
CHESS = parse_board("chessboard:9x6:25mm")
CAMERA = Camera(np.array([[600.0, 0.0, 320.0], [0.0, 600.0, 240.0], [0.0, 0.0, 1.0]]),
                np.array([-0.1, 0.04, 0.0, 0.0, 0.0]), (640, 480))


def same(a: Outcome, b: Outcome) -> bool:
    """Outcomes equal to the last bit: every candidate's ids, pixels and method, the reason, size."""
    if (a.detection is None) != (b.detection is None) or (a.reason, a.size, a.depth) != (b.reason, b.size, b.depth):
        return False
    if a.detection is None:
        return True
    ca, cb = a.detection.candidates(), b.detection.candidates()
    return len(ca) == len(cb) and all(x.method == y.method and np.array_equal(x.ids, y.ids)
                                      and np.array_equal(x.image_points, y.image_points)
                                      and np.array_equal(x.object_points, y.object_points) for x, y in zip(ca, cb))


@pytest.fixture(scope="module")
def chess_folder(tmp_path_factory) -> Path:
    """Eight rendered 640 x 480 chessboard views (blur, noise, distortion) and one without a board."""
    folder = tmp_path_factory.mktemp("chess")
    rng = np.random.default_rng(3)
    for i in range(8):
        T = view_pose(CHESS, rng.uniform(380, 520), tilt=tuple(rng.uniform(-0.35, 0.35, 3)), roll=rng.uniform(-0.6, 0.6))
        cv2.imwrite(str(folder / f"{i}.png"), render(CHESS, CAMERA, T, blur=0.7, noise=1.5, rng=rng))
    cv2.imwrite(str(folder / "8.png"), np.full((480, 640), 128, np.uint8))
    return folder


def test_parallel_and_serial_detection_are_identical_and_in_order(chess_folder):
    """Circle grids (bundled real images) and chessboards (every flag set; one image without a
    board): two detecting threads give the serial outcomes, bit for bit, in order."""
    items = [(str(f), parse_board(CIRCLES), None) for f in list_images(image_example_dir() / "images")[:6]]
    items += [(str(f), CHESS, None) for f in list_images(chess_folder)[-4:]]
    serial = detection_pool.run(items, 1)
    finished: list[int] = []
    parallel = detection_pool.run(items, 2, done=lambda: finished.append(1))
    assert len(parallel) == len(items) and all(same(a, b) for a, b in zip(serial, parallel))
    assert len(finished) == len(items)
    assert sum(o.detection is None for o in parallel) == 1 and parallel[-1].reason.startswith("board not found")
    assert parallel[0].detection.image_points.flags.writeable is False


def test_workers_must_be_a_whole_number(monkeypatch):
    from handeye.base.errors import InputError

    with pytest.raises(InputError, match="whole number >= 1"):
        detection_pool.run([], 0)
    monkeypatch.setenv(detection_pool.WORKERS_VARIABLE, "3")
    assert detection_pool.default_workers() == 3


def cached_circle_grid(tmp_path: Path, count: int) -> tuple[list[Path], Any, Path, list[Outcome]]:
    """The bundled circle grid's first `count` images copied, detected once into a cache of their
    own: (files, board, cache folder, the outcomes)."""
    folder = tmp_path / "images"
    shutil.copytree(image_example_dir() / "images", folder)
    files = list_images(folder)[:count]
    board = parse_board(CIRCLES)
    cache = tmp_path / "cache"
    return files, board, cache, detection_plan.detect_set(files, board, cache=cache, workers=1)


def test_a_cache_hit_is_identical_and_a_changed_image_or_board_misses(tmp_path, monkeypatch):
    """Second run: every image from the cache (detection never called), the same outcomes; one
    image changed by one pixel, another board and changed detector code each miss; a damaged
    entry is a miss, not an error; HANDEYE_NO_CACHE writes nothing."""
    files, board, cache, first = cached_circle_grid(tmp_path, 5)
    entries = sorted((cache / "detections").rglob("*.npz"))
    assert len(entries) == 5

    ran: list[int] = []
    real_run = detection_pool.run

    def counting(items, *args, **kwargs):
        ran.append(len(items))
        return real_run(items, *args, **kwargs)

    monkeypatch.setattr(detection_pool, "run", counting)
    again = detection_plan.detect_set(files, board, cache=cache, workers=1)
    assert sum(ran) == 0 and all(same(a, b) for a, b in zip(first, again))

    image = cv2.imread(str(files[2]), cv2.IMREAD_GRAYSCALE)
    image[0, 0] ^= 1
    cv2.imwrite(str(files[2]), image)
    store = DetectionCache(cache)
    store._path(store.key(detection_cache.file_digest(files[0]), board, ("flag sets", None))).write_bytes(b"not npz")
    changed = detection_plan.detect_set(files, board, cache=cache, workers=1)
    assert sum(ran) == 2  # the changed image and the damaged entry's image
    assert all(same(a, b) for a, b in zip(first, changed))  # one pixel moves no circle centre here

    ran.clear()
    other = dataclasses.replace(board, spacing=25.0)
    detection_plan.detect_set(files, other, cache=cache, workers=1)
    assert sum(ran) == 5

    ran.clear()  # another detector's code: every entry is stale
    monkeypatch.setattr(detection_cache, "_code", lambda: "changed detector")
    detection_plan.detect_set(files, board, cache=cache, workers=1)
    assert sum(ran) == 5

    monkeypatch.setenv("HANDEYE_NO_CACHE", "1")
    off = tmp_path / "off"
    monkeypatch.setenv("HANDEYE_CACHE_DIR", str(off))
    detection_plan.detect_set(files, board, workers=1)
    assert not off.exists()


def test_the_cache_is_the_users_own_folder_unless_switched_off(monkeypatch, tmp_path):
    from handeye.vision.detection_cache import default_dir

    monkeypatch.delenv("HANDEYE_CACHE_DIR", raising=False)
    monkeypatch.delenv("HANDEYE_NO_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert default_dir() == tmp_path / "handeye"
    monkeypatch.setenv("HANDEYE_NO_CACHE", "1")  # as the suite runs (tests/conftest.py)
    assert default_dir() is None and DetectionCache.resolve(None) is None
    assert DetectionCache.resolve(False) is None


def test_the_flag_set_plan_keeps_the_corners_of_the_full_run(chess_folder, monkeypatch):
    """The eight chessboard views: the probe (4 images) plans the flag sets; the corners `choose`
    then keeps on every image are those it keeps with every flag set run on every image."""
    files = [f for f in list_images(chess_folder) if f.stem != "8"]
    full = [detection_pool.run([(str(f), CHESS, None)], 1)[0] for f in files]
    monkeypatch.setattr(detection_plan, "PLAN_MIN_IMAGES", 6)
    planned = detection_plan.detect_set(files, CHESS, cache=False, workers=1)
    probe = detection_plan.probe_indices(len(files))
    plan = detection_plan.flag_set_plan([full[k] for k in probe], None)
    assert plan is not None and len(plan) < 4  # something was left out
    assert any(len(p.detection.candidates()) < len(f.detection.candidates()) for p, f in zip(planned, full))
    kept_full = choose([o.detection for o in full], None, (640, 480)).detections
    kept_planned = choose([o.detection for o in planned], None, (640, 480)).detections
    for a, b in zip(kept_full, kept_planned):
        assert a.method == b.method
        np.testing.assert_array_equal(a.image_points, b.image_points)


def test_the_camera_is_calibrated_once_per_image_set(monkeypatch):
    """The bundled circle grid: choose's calibration of the kept corners is the one the stations
    use (no second calibration of the same corners), equal to calibrating them afresh."""
    from handeye.vision import best_corners
    from handeye.vision.intrinsics import calibrate_camera

    calls: list[int] = []

    def counted(detections, size, **kwargs):
        calls.append(len(detections))
        return calibrate_camera(detections, size, **kwargs)

    monkeypatch.setattr(best_corners, "calibrate_camera", counted)
    monkeypatch.setattr(image_set_module, "calibrate_camera", counted)
    images = images_and_poses(image_example_dir() / "images", parse_board(CIRCLES), None, setup="eye-in-hand",
                              cache=False, workers=1)
    assert len(images) == 15 and calls == [15] * len(calls)
    choice_rounds = len(calls)
    fresh = calibrate_camera([_Points(u, o) for u, o in zip(images.observations.image_points,
                                                            images.observations.object_points)], (640, 480))
    assert np.array_equal(fresh.camera.K, images.camera.K) and fresh.rms == images.calibration.rms
    assert choice_rounds <= 2  # choose's rounds only; images_and_poses took the last


@dataclasses.dataclass
class _Points:
    image_points: np.ndarray
    object_points: np.ndarray


def test_the_progress_bar_shows_on_a_terminal_only(capfd):
    """Under pytest stderr is no terminal: no bar, nothing written."""
    from handeye.framework.progress import progress_bar

    with progress_bar(3, "detecting the board", "image") as bar:
        bar.update()
        assert bar.disable
    with progress_bar(3, "detecting the board", "image", show=False) as bar:
        assert bar.disable
    assert capfd.readouterr().err == ""


def test_an_image_the_plan_numbers_wrongly_runs_every_flag_set(chess_folder):
    """A chessboard numbered wrongly (its first two rows swapped; what the planned flag sets could
    agree on) fits the camera far worse than the others: `doubtful` names it, and only it, with the
    intrinsics given and calibrated."""
    from handeye.vision.detection import Detection

    files = [f for f in list_images(chess_folder) if f.stem != "8"][:5]
    outcomes = dict(enumerate(detection_pool.run([(str(f), CHESS, ("SB",)) for f in files], 1)))
    assert detection_plan.doubtful(outcomes, None) == [] and detection_plan.doubtful(outcomes, CAMERA) == []
    d = outcomes[3].detection
    swapped = d.image_points.reshape(CHESS.rows, CHESS.cols, 2)[[1, 0, *range(2, CHESS.rows)]].reshape(-1, 2)
    outcomes[3] = dataclasses.replace(outcomes[3], detection=Detection.of(CHESS, d.ids, swapped, d.method))
    assert detection_plan.doubtful(outcomes, CAMERA) == [3]
    assert detection_plan.doubtful(outcomes, None) == [3]


# -- the crop around a chessboard (handeye.vision.chessboard_region) ---------------------------------
BIG_CAMERA = Camera(np.array([[1000.0, 0.0, 640.0], [0.0, 1000.0, 512.0], [0.0, 0.0, 1.0]]),
                    np.array([-0.3, 0.12, 0.0, 0.0, 0.0]), (1280, 1024))
BIG_CHESS = parse_board("chessboard:10x7:30mm")


@pytest.fixture(scope="module")
def big_views() -> list[tuple[np.ndarray, np.ndarray]]:
    """Three rendered 1280 x 1024 views (strong barrel distortion, blur, noise; one board off centre
    near the image's corner) and their true corners."""
    from handeye.vision.render import project

    rng = np.random.default_rng(5)
    views = []
    for shift in ((0.0, 0.0), (-150.0, -120.0), (120.0, 60.0)):
        T = view_pose(BIG_CHESS, rng.uniform(700, 800), tilt=tuple(rng.uniform(-0.4, 0.4, 3)), roll=rng.uniform(-0.5, 0.5))
        T[:2, 3] += shift
        views.append((render(BIG_CHESS, BIG_CAMERA, T, blur=0.8, noise=2.0, rng=rng), project(BIG_CHESS, BIG_CAMERA, T)))
    return views


def test_the_crop_finds_the_corners_of_the_full_image(big_views, chess_folder):
    """SB with ACCURACY, with NORMALIZE | ACCURACY and without flags finds the board in the crop (no
    search of the full image), its corners within hundredths of a pixel of the full image's (0.013
    px RMS measured on the bench's renders) and as near the truth."""
    from handeye.vision.chessboard_region import Region

    accuracy, normalize = cv2.CALIB_CB_ACCURACY, cv2.CALIB_CB_NORMALIZE_IMAGE
    images = [(gray, truth, (BIG_CHESS.cols, BIG_CHESS.rows)) for gray, truth in big_views]
    images += [(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE), None, (CHESS.cols, CHESS.rows))
               for f in list_images(chess_folder)[:4]]
    differences, truth_errors = [], {"crop": [], "full": []}
    sb, searched = cv2.findChessboardCornersSB, []

    def recorded(image, pattern, flags=0):
        searched.append(image.shape)
        return sb(image, pattern, flags=flags)

    for gray, truth, size in images:
        for flags in (accuracy, normalize | accuracy, 0):
            region, searched[:] = Region(gray, size), []
            with pytest.MonkeyPatch.context() as patched:
                patched.setattr(cv2, "findChessboardCornersSB", recorded)
                crop = region.find(flags)
            assert gray.shape not in searched  # found in the crop, not by the fall-back
            found, full = sb(gray, size, flags=flags)
            assert found and crop is not None
            x0, y0, x1, y1 = region.box
            assert (x1 - x0) * (y1 - y0) < 0.7 * gray.size
            full = full.reshape(-1, 2)
            differences.append(np.linalg.norm(crop - full, axis=1))
            if truth is not None and flags == accuracy:
                truth_errors["crop"].append(np.sqrt(np.mean(np.sum((crop - truth) ** 2, axis=1))))
                truth_errors["full"].append(np.sqrt(np.mean(np.sum((full - truth) ** 2, axis=1))))
    differences = np.concatenate(differences)
    assert differences.max() < 0.3 and np.sqrt(np.mean(differences ** 2)) < 0.03
    assert np.mean(truth_errors["crop"]) < np.mean(truth_errors["full"]) + 0.003
    assert np.mean(truth_errors["crop"]) < 0.06


def test_normalize_alone_searches_the_crop_of_the_equalised_image(big_views):
    """SB with NORMALIZE_IMAGE alone searches the crop of the equalised full image (no search of
    the full image) and finds its corners there within 0.05 px RMS (0.3 px at most) of the full
    image's, at most 5 % further from the truth (measured: 0.024 px RMS apart here, 0.028 on the
    bench's 30 renders, where they lay 0.0761 px from the truth against 0.0748); when the crop
    fails, the full image's corners to the last bit."""
    from handeye.vision.chessboard_region import Region

    normalize, sb = cv2.CALIB_CB_NORMALIZE_IMAGE, cv2.findChessboardCornersSB
    size = (BIG_CHESS.cols, BIG_CHESS.rows)
    differences, errors = [], {"crop": [], "full": []}
    for gray, truth in big_views:
        searched = []

        def recorded(image, pattern, flags=0, searched=searched):
            searched.append(image.shape)
            return sb(image, pattern, flags=flags)

        with pytest.MonkeyPatch.context() as patched:
            patched.setattr(cv2, "findChessboardCornersSB", recorded)
            crop = Region(gray, size).find(normalize)
        assert crop is not None and gray.shape not in searched
        found, full = sb(gray, size, flags=normalize)
        assert found
        full = full.reshape(-1, 2).astype(np.float64)
        differences.append(np.linalg.norm(crop - full, axis=1))
        errors["crop"].append(np.sum((crop - truth) ** 2, axis=1))  # OpenCV's order is the truth's here
        errors["full"].append(np.sum((full - truth) ** 2, axis=1))
    differences = np.concatenate(differences)
    assert np.sqrt(np.mean(differences ** 2)) < 0.05 and differences.max() < 0.3
    crop_error, full_error = (np.sqrt(np.mean(np.concatenate(errors[k]))) for k in ("crop", "full"))
    assert crop_error < 1.05 * full_error and crop_error < 0.1

    gray = big_views[1][0]

    def fails_on_crops(image, pattern, flags=0):
        return sb(image, pattern, flags=flags) if image.shape == gray.shape else (False, None)

    with pytest.MonkeyPatch.context() as patched:
        patched.setattr(cv2, "findChessboardCornersSB", fails_on_crops)
        region = Region(gray, size)
        fallen_back = region.find(normalize)
    assert region.box is not None
    assert np.array_equal(fallen_back, sb(gray, size, flags=normalize)[1].reshape(-1, 2).astype(np.float64))


def test_a_board_the_crop_misses_is_searched_in_the_full_image(big_views, monkeypatch):
    """No board found before is lost: when SB fails on the crop, when the board is located
    wrongly, or not at all, the corners are those of the full image, to the last bit."""
    from handeye.vision import chessboard_region
    from handeye.vision.chessboard_region import Region

    gray, _ = big_views[1]
    size, accuracy = (BIG_CHESS.cols, BIG_CHESS.rows), cv2.CALIB_CB_ACCURACY
    full = cv2.findChessboardCornersSB(gray, size, flags=accuracy)[1].reshape(-1, 2).astype(np.float64)
    sb = cv2.findChessboardCornersSB

    def fails_on_crops(image, pattern, flags=0):
        return sb(image, pattern, flags=flags) if image.shape == gray.shape else (False, None)

    with monkeypatch.context() as patched:
        patched.setattr(cv2, "findChessboardCornersSB", fails_on_crops)
        region = Region(gray, size)
        assert np.array_equal(region.find(accuracy), full) and region.box is not None
    located = chessboard_region.locate(gray, size)
    box = chessboard_region.crop_box(located, size, gray.shape)
    for wrong in (located + (400.0, 300.0), None):  # elsewhere (no board in the crop), nowhere
        monkeypatch.setattr(chessboard_region, "locate", lambda image, pattern, wrong=wrong: wrong)
        assert np.array_equal(Region(gray, size).find(accuracy), full)
    # the crop holds the board, but its corners lie off the located ones: not taken
    monkeypatch.setattr(chessboard_region, "locate", lambda image, pattern: located + (400.0, 300.0))
    monkeypatch.setattr(chessboard_region, "crop_box", lambda corners, pattern, shape: box)
    assert np.array_equal(Region(gray, size).find(accuracy), full)
    blank = np.full_like(gray, 128)
    monkeypatch.undo()
    assert chessboard_region.locate(blank, size) is None and Region(blank, size).find(accuracy) is None


def test_corners_off_the_located_board_are_not_taken():
    """A crop's corners must lie on the located ones: a board found a square off is not."""
    from handeye.vision.chessboard_region import (
        MARGIN_PX,
        MARGIN_SQUARES,
        _agree,
        crop_box,
    )

    grid = np.stack(np.meshgrid(np.arange(10) * 40.0 + 100, np.arange(7) * 40.0 + 80), axis=-1).reshape(-1, 2)
    assert _agree(grid + 3.0, grid, (10, 7)) and not _agree(grid + (40.0, 0.0), grid, (10, 7))
    pad = int(max(MARGIN_SQUARES * 40, MARGIN_PX))
    assert crop_box(grid, (10, 7), (1024, 1280)) == (100 - pad, 80 - pad, 460 + pad + 1, 320 + pad + 1)
    assert crop_box(grid * 3.0 - 200.0, (10, 7), (1024, 1280)) is None  # most of the image: the full one


def test_the_cache_key_holds_the_chessboard_detector_code():
    """A change of the crop's code must miss the cache entries of the old one."""
    assert {"detect", "chessboard_region", "detection"} <= set(detection_cache.DETECTOR_MODULES)
    for name in detection_cache.DETECTOR_MODULES:
        assert (Path(detection_cache.__file__).parent / f"{name}.py").is_file()


@pytest.mark.parametrize("damage", ["corners not finite", "corners far outside the image", "ids outside the board"])
def test_an_entry_whose_contents_no_detection_gives_is_a_miss(tmp_path, damage):
    """An entry that reads as an archive but holds what no detection gives (NaN corners, corners a
    million pixels off, ids the board has not) is a miss: detected again, the same outcome as the
    first run, no error (NaN corners ended in an internal IndexError)."""
    files, board, cache, first = cached_circle_grid(tmp_path, 3)
    entry = sorted((cache / "detections").rglob("*.npz"))[0]
    with np.load(entry, allow_pickle=False) as stored:
        arrays = {k: stored[k] for k in stored.files}
    if damage == "corners not finite":
        arrays["points"] = np.full(arrays["points"].shape, np.nan)
    elif damage == "corners far outside the image":
        arrays["points"] = arrays["points"] + 1e6
    else:
        arrays["ids"] = arrays["ids"] + 10**6
    with entry.open("wb") as fh:
        np.savez(fh, **arrays)
    again = detection_plan.detect_set(files, board, cache=cache, workers=1)
    assert all(same(a, b) for a, b in zip(first, again))
