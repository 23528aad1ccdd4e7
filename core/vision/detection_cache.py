"""Board detections kept on disk by image content, so that running the same images again (other
solver, other setup, other options) skips the detection, which is nearly all of the time an image
set takes (30 chessboard images of 1.3 MP: ~45 s of detection against ~1 s for the rest).

An entry is keyed by the SHA-256 of the image file's bytes, the board (every field of `Board`),
the detector settings (the chessboard flag-set plan), the versions of handeye, OpenCV and of this
format, and the detectors' source code: a changed image, board, setting, OpenCV or detector gives
another key, and the old entry is simply never read again. An entry is one ``.npz`` file (arrays and a JSON header, no pickle), written
to a temporary name and renamed, so a reader sees a whole entry or none; one that cannot be read,
or whose header names another key, is a miss (and removed). Unreadable image files are not cached.

Where: `HANDEYE_CACHE_DIR` if set, else the user's cache folder (``$XDG_CACHE_HOME/handeye`` or
``~/.cache/handeye``; ``~/Library/Caches/handeye`` on macOS, ``%LOCALAPPDATA%/handeye/cache`` on
Windows). Off with `HANDEYE_NO_CACHE=1` (or ``cache=False`` in the library call); the test suite
switches it off (tests/conftest.py), and a test that wants a cache gives a temporary folder.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

from handeye.vision.boards import Board
from handeye.vision.detection import Detection
from handeye.vision.image_detection import Outcome

#: bump when what an entry holds, or what the detectors return, changes
FORMAT = 1
#: the modules whose code decides what a detection is (their source is part of every key)
DETECTOR_MODULES = ("detect", "chessboard_region", "detection", "circlegrid", "aprilgrid", "image_detection", "image_set",
                    "boards")
#: environment variables: the cache folder, and switching the cache off
DIR_VARIABLE = "HANDEYE_CACHE_DIR"
OFF_VARIABLE = "HANDEYE_NO_CACHE"


def default_dir() -> Path | None:
    """The cache folder the environment asks for (module docstring), None when caching is off."""
    if os.environ.get(OFF_VARIABLE, "").strip() not in ("", "0"):
        return None
    if os.environ.get(DIR_VARIABLE):
        return Path(os.environ[DIR_VARIABLE])
    if sys.platform == "win32" and os.environ.get("LOCALAPPDATA"):
        return Path(os.environ["LOCALAPPDATA"]) / "handeye" / "cache"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "handeye"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "handeye"


class DetectionCache:
    """Detections by image content under `root` (module docstring)."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root) / "detections"

    @classmethod
    def resolve(cls, cache: bool | str | Path | None) -> DetectionCache | None:
        """The cache a caller asked for: None / True the environment's (`default_dir`), False none,
        a path that folder."""
        if cache is False:
            return None
        root = default_dir() if cache is None or cache is True else Path(cache)
        return None if root is None else cls(root)

    def key(self, digest: str, board: Board, settings: object) -> str:
        """The entry's key: image bytes' digest, board, detector settings and versions."""
        from handeye import __version__

        text = json.dumps([FORMAT, __version__, cv2.__version__, _code(), repr(board), repr(settings), digest])
        return hashlib.sha256(text.encode()).hexdigest()

    def _path(self, key: str) -> Path:
        return self.root / key[:2] / f"{key}.npz"

    def get(self, key: str, board: Board) -> Outcome | None:
        """The stored outcome of `key`, None when there is none or it cannot be read (then removed)."""
        path = self._path(key)
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as stored:
                header = json.loads(str(stored["header"]))
                if header["key"] != key:
                    raise ValueError("another entry's key")
                return _outcome(header, stored["ids"], stored["points"], board)
        except Exception:  # noqa: BLE001 -- any damage makes a miss, never an error
            path.unlink(missing_ok=True)
            return None

    def put(self, key: str, outcome: Outcome) -> None:
        """Store `outcome` under `key` (not when the image was unreadable); a folder that cannot be
        written leaves things uncached, silently."""
        if not outcome.readable:
            return
        found = () if outcome.detection is None else outcome.detection.candidates()
        header = {"key": key, "reason": outcome.reason, "size": list(outcome.size),
                  "depth": None if outcome.depth is None else list(outcome.depth),
                  "methods": [d.method for d in found], "counts": [len(d) for d in found]}
        ids = np.concatenate([d.ids for d in found]) if found else np.zeros(0, np.int64)
        points = np.concatenate([d.image_points for d in found]) if found else np.zeros((0, 2))
        path = self._path(key)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            handle, temporary = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        except OSError:
            return
        try:
            with os.fdopen(handle, "wb") as out:
                np.savez(out, header=np.array(json.dumps(header)), ids=ids, points=points)
            os.replace(temporary, path)
        except OSError:
            with contextlib.suppress(OSError):
                os.unlink(temporary)


def file_digest(path: str | Path) -> str | None:
    """SHA-256 of the file's bytes (None when it cannot be read: such a file is not cached)."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


@functools.cache
def _code() -> str:
    """Digest of the detectors' own source (`DETECTOR_MODULES`): a changed detector never reads an
    entry of the old one, even within one handeye version."""
    digest = hashlib.sha256()
    for name in DETECTOR_MODULES:
        digest.update((Path(__file__).parent / f"{name}.py").read_bytes())
    return digest.hexdigest()


def _outcome(header: dict, ids: np.ndarray, points: np.ndarray, board: Board) -> Outcome:
    """The `Outcome` an entry holds (its candidates split by their point counts)."""
    ends = np.cumsum(header["counts"]).tolist()
    if (ends[-1] if ends else 0) != len(ids) or len(ids) != len(points):
        raise ValueError("counts do not match the arrays")
    width, height = (int(header["size"][0]), int(header["size"][1]))
    points = np.asarray(points, dtype=float).reshape(len(points), 2)
    inside = np.isfinite(points).all() and (points >= -1).all() and (points[:, 0] <= width).all() \
        and (points[:, 1] <= height).all()
    if not inside or not (np.asarray(ids) >= 0).all() or not (np.asarray(ids) < len(board.object_points())).all():
        raise ValueError("corners outside the image or ids outside the board")  # damaged: a miss
    found = [Detection.of(board, ids[a:b], points[a:b], m)
             for m, a, b in zip(header["methods"], [0, *ends[:-1]], ends)]
    detection = found[0].with_alternatives(tuple(found[1:])) if found else None
    depth = None if header["depth"] is None else (str(header["depth"][0]), float(header["depth"][1]))
    return Outcome(detection, header["reason"], (int(header["size"][0]), int(header["size"][1])), depth)

