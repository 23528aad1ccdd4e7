"""Reading an image file for board detection: grey, at its own depth (`read_any`), scaled to the
8 bits the detectors need (`to_8bit`), OpenCV's own warnings kept off the terminal."""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from handeye.base.errors import InputError

#: imread flags: one grey channel at the file's own depth (8, 16 bit, float). Unlike IMREAD_UNCHANGED
#: this still turns a JPEG by its EXIF orientation; IMREAD_UNCHANGED is the fallback for what it
#: cannot convert (a float colour TIFF)
_READ_FLAGS = cv2.IMREAD_GRAYSCALE | cv2.IMREAD_ANYDEPTH

def read_image(path: str | Path) -> np.ndarray:
    """The image file `path` as an 8-bit grey array (`to_8bit` of `read_any`). InputError (one
    line, naming the file) when it cannot be read or holds no usable values."""
    return to_8bit(read_any(Path(path)), Path(path).name)


def read_any(path: Path) -> np.ndarray:
    """The image as stored, grey (2-D), at its own depth. OpenCV's warnings are silenced: a file it
    cannot read is reported here, once, as an InputError."""
    with _opencv_quiet():
        image = cv2.imread(str(path), _READ_FLAGS)
        if image is None:
            image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise InputError(f"{path.name}: unreadable image file (not an image, damaged, or a kind OpenCV cannot "
                         "decode); save it as 8- or 16-bit PNG")
    if image.ndim == 3 and image.shape[2] in (3, 4):
        code = cv2.COLOR_BGR2GRAY if image.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        work = image if image.dtype in (np.uint8, np.uint16, np.float32) else image.astype(np.float32)
        image = cv2.cvtColor(work, code)
    elif image.ndim == 3 and image.shape[2] == 1:
        image = image[..., 0]
    if image.ndim != 2:
        raise InputError(f"{path.name}: an image of shape {image.shape} is neither grey nor colour")
    return image


_quiet_lock = threading.Lock()
_quiet_depth = 0
_quiet_saved: int | None = None


@contextlib.contextmanager
def _opencv_quiet() -> Iterator[None]:
    """OpenCV's own log (its "[ WARN ]" lines on stderr) off for the block, restored after. Its
    level is one global setting and images are read on several threads at once
    (`handeye.vision.detection_pool`): the first block to enter turns it off, the last to leave
    restores it."""
    global _quiet_depth, _quiet_saved
    with _quiet_lock:
        if _quiet_depth == 0:
            _quiet_saved = cv2.utils.logging.getLogLevel()
            cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
        _quiet_depth += 1
    try:
        yield
    finally:
        with _quiet_lock:
            _quiet_depth -= 1
            if _quiet_depth == 0 and _quiet_saved is not None:
                cv2.utils.logging.setLogLevel(_quiet_saved)


def to_8bit(image: np.ndarray, name: str = "image") -> np.ndarray:
    """A grey image as uint8: 8-bit passed through; any other depth (16-bit, e.g. 12-bit data in a
    16-bit PNG, or float) scaled linearly from its own range (min..max) to 0..255, as the detectors
    need 8 bits and only contrast matters to them (OpenCV's own 16 -> 8 bit conversion divides by
    256, which leaves 12-bit data at 0..15, too dark to find a board). InputError for NaN or
    infinite pixels."""
    if image.dtype == np.uint8:
        return image
    values = image.astype(np.float64)
    if not np.all(np.isfinite(values)):
        raise InputError(f"{name}: a {depth_name(image.dtype)} image with NaN or infinite pixels; save it with "
                         "finite values (or as 8- or 16-bit PNG)")
    low, high = float(values.min()), float(values.max())
    scaled = (values - low) * (255.0 / (high - low)) if high > low else np.zeros_like(values)
    return np.rint(scaled).astype(np.uint8)


def depth_name(dtype: np.dtype) -> str:
    """'16-bit', '32-bit float', ... for an image's dtype."""
    dtype = np.dtype(dtype)
    kind = {"f": " float", "i": " signed"}.get(dtype.kind, "")
    return f"{dtype.itemsize * 8}-bit{kind}"
