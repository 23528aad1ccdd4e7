"""Camera intrinsics: read them from the files calibration tools write, or calibrate them from
board detections.

`load_camera(path)` reads

- OpenCV FileStorage files (``.yaml``/``.yml`` starting with ``%YAML``, ``.xml``, ``.json``), as
  written by OpenCV's calibration sample: ``camera_matrix``, ``distortion_coefficients``,
  ``image_width``, ``image_height`` (read with ``cv2.FileStorage``);
- ROS ``camera_info`` YAML (camera_calibration's output): ``camera_matrix: {rows, cols, data}``,
  ``distortion_model`` ``plumb_bob`` or ``rational_polynomial``, ``distortion_coefficients``,
  ``image_width``, ``image_height``; also a dumped CameraInfo message (``K``/``k``, ``D``/``d``,
  ``width``, ``height``);
- ROS-Industrial industrial_calibration's ``cal_data.yaml`` (``intrinsics: {fx, fy, cx, cy}``, no
  distortion, no image size).

Any of them may state the intrinsics' 1-sigma in pixels (`Camera.std`), which every answer
calibrated with them carries in its own 1-sigma (`handeye.vision.intrinsics_effect`):
``std_px: {fx, fy, cx, cy}`` (as handeye's result file writes a camera's), a ``std`` mapping
inside ``intrinsics``, or OpenCV's ``stdDeviationsIntrinsics`` vector from
``calibrateCameraExtended`` (its first four: fx, fy, cx, cy), spelled
``std_deviations_intrinsics`` too. A file without one is taken as known as well as the images
themselves know the camera (`handeye.vision.intrinsics_check.given_std`).

`calibrate_camera(detections, image_size)` runs ``cv2.calibrateCameraExtended`` on the board
points of several images. The model is OpenCV's default pinhole with k1, k2, p1, p2, k3; k3 is
fixed at 0 with fewer than `K3_MIN_VIEWS` images (a sixth-order radial term is poorly determined
by few planar views and then mostly absorbs noise). Fewer than `MIN_VIEWS` images are refused.

Nothing passed in is modified; bad input raises `handeye.base.errors.InputError` with a one-line message.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, Protocol

import cv2
import numpy as np

from handeye.base.errors import InputError
from handeye.io.input_files import MAX_DEPTH, load_json, load_yaml, number
from handeye.vision.observations import Camera

#: fewest images with the board found that `calibrate_camera` accepts
MIN_VIEWS = 3
#: from this many images on, k3 is estimated; below, it is fixed at 0 (CALIB_FIX_K3)
K3_MIN_VIEWS = 10
#: ROS distortion models read, and how many coefficients each has
ROS_MODELS = {"plumb_bob": 5, "rational_polynomial": 8}
#: accepted key spellings (lower case) of the camera matrix, distortion and image size
_K_KEYS = ("camera_matrix", "cameramatrix", "k", "intrinsic_matrix", "intrinsics_matrix")
_D_KEYS = ("distortion_coefficients", "dist_coeffs", "distcoeffs", "distortion", "d", "dist")
_W_KEYS = ("image_width", "width", "imagewidth")
_H_KEYS = ("image_height", "height", "imageheight")
_STD_KEYS = ("std_px", "std", "stddeviationsintrinsics", "std_deviations_intrinsics", "intrinsics_std")
#: the order of the 1-sigma stated as a list (OpenCV's stdDeviationsIntrinsics starts so)
_STD_ORDER = ("fx", "fy", "cx", "cy")


class PointsOfImage(Protocol):
    """What `calibrate_camera` needs of one image's detection (`handeye.vision.detect.Detection`)."""

    image_points: np.ndarray
    object_points: np.ndarray


@dataclasses.dataclass(frozen=True)
class CameraCalibration:
    """The result of `calibrate_camera`: the camera, the RMS reprojection error of each image and
    of all points (pixels), 1-sigma of fx, fy, cx, cy (pixels) from OpenCV, and the model used.
    `opencv_std`: OpenCV's own 1-sigma where `std_fx_fy_cx_cy` was widened by a jackknife over
    the images (`handeye.vision.intrinsics_check.with_jackknife`: OpenCV's is too small on real
    images), else None. `board_poses`: per image, the board's pose in the camera that the
    calibration solved with the intrinsics, (n, 6) as OpenCV's rvec then tvec (the jackknife
    linearises about them), or None where not known."""

    camera: Camera
    per_image_rms: np.ndarray
    rms: float
    std_fx_fy_cx_cy: np.ndarray
    model: str
    opencv_std: np.ndarray | None = None
    board_poses: np.ndarray | None = None

    def __iter__(self):  # (camera, per-image RMS, overall RMS), as the function's documented triple
        return iter((self.camera, self.per_image_rms, self.rms))


# ----------------------------------------------------------------------------- loading


def load_camera_of(path: str | Path | None, field: str) -> Camera | None:
    """`load_camera` of a cell file's intrinsics entry `field` (None: not given), its errors
    prefixed with the field's name."""
    if path is None:
        return None
    try:
        return load_camera(path)
    except InputError as exc:
        raise InputError(f"`{field}`: {exc}") from None


def load_camera(path: str | Path) -> Camera:
    """The intrinsics in `path` (formats in the module docstring) as a `Camera`."""
    path = Path(path)
    src = f"intrinsics file {str(path)!r}"
    if not path.is_file():
        raise InputError(f"{src} not found; give --intrinsics an existing file")
    ext = path.suffix.lower()
    if ext not in (".yaml", ".yml", ".xml", ".json"):
        raise InputError(f"{src}: unsupported extension {ext or '(none)'!r}; give a .yaml, .yml, .xml or .json file")
    text = path.read_text(encoding="utf-8-sig", errors="replace")
    if ext == ".xml" or text.lstrip().startswith("%YAML"):
        fields = _read_file_storage(path, src)
    elif ext == ".json":
        fields = load_json(text, src)
    else:
        fields = load_yaml(text, src)
    if not isinstance(fields, dict):
        raise InputError(f"{src}: expected a mapping of camera fields (camera_matrix, distortion_coefficients, ...)")
    return _camera_from_fields(fields, src)


def _read_file_storage(path: Path, src: str) -> dict[str, Any]:
    """The top-level nodes of an OpenCV FileStorage file: matrices as arrays, numbers, strings."""
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except cv2.error:
        raise InputError(f"{src}: OpenCV cannot read it as a FileStorage file (YAML with '%YAML:1.0', XML or "
                         "JSON)") from None
    try:
        if not fs.isOpened():
            raise InputError(f"{src}: OpenCV cannot open it as a FileStorage file")
        root = fs.root()
        names = root.keys()
        return {key: _node_value(root.getNode(key), src) for key in names}
    finally:
        fs.release()


def _node_value(node: cv2.FileNode, src: str, depth: int = 1) -> Any:
    """A FileStorage node as Python values; InputError where it nests deeper than any intrinsics
    file does (`handeye.io.input_files.MAX_DEPTH`)."""
    if depth > MAX_DEPTH:
        raise InputError(f"{src}: nested more than {MAX_DEPTH} levels deep; an intrinsics file holds a 3x3 matrix, "
                         "a list of distortion coefficients and the image size")
    if node.isNone():
        return None
    if node.isInt() or node.isReal():
        return node.real()
    if node.isString():
        return node.string()
    if node.isSeq():
        return [_node_value(node.at(i), src, depth + 1) for i in range(node.size())]
    if node.isMap():
        names = node.keys()
        if "data" in names and "rows" in names:
            mat = node.mat()
            if mat is not None:
                return np.asarray(mat, dtype=float).tolist()
        return {key: _node_value(node.getNode(key), src, depth + 1) for key in names}
    return None


def _get(fields: dict[str, Any], keys: tuple[str, ...]) -> Any:
    lowered = {str(k).lower(): v for k, v in fields.items()}
    return next((lowered[k] for k in keys if k in lowered), None)


def _numbers(value: Any, what: str, src: str) -> np.ndarray:
    """A matrix written as a nested list, a flat list, or ROS' {rows, cols, data}."""
    if isinstance(value, dict):
        value = value.get("data")
    try:
        out = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        out = np.asarray([np.nan])
    if out.size == 0 and what == "distortion_coefficients":
        return out.ravel()
    if out.ndim == 0 or not np.all(np.isfinite(out)):
        raise InputError(f"{src}: {what} must be a list of finite numbers (or rows/cols/data), got {value!r}"[:200])
    return out


def _scalar(value: Any, what: str, src: str) -> float:
    out = number(value)
    if out is None or not np.isfinite(out):
        raise InputError(f"{src}: {what} must be a finite number, got {str(value)[:40]!r}")
    return out


def _camera_from_fields(fields: dict[str, Any], src: str) -> Camera:
    cal = fields.get("intrinsics")
    if isinstance(cal, dict):  # ROS-Industrial cal_data.yaml
        missing = [k for k in ("fx", "fy", "cx", "cy") if k not in cal]
        if missing:
            raise InputError(f"{src}: 'intrinsics' lacks {', '.join(missing)}; give fx, fy, cx, cy")
        v = {k: _scalar(cal[k], f"intrinsics.{k}", src) for k in ("fx", "fy", "cx", "cy")}
        K = np.array([[v["fx"], 0.0, v["cx"]], [0.0, v["fy"], v["cy"]], [0.0, 0.0, 1.0]])
        return _camera(K, np.zeros(0), None, src, _std(_get(cal, _STD_KEYS), "intrinsics.std", src))
    k_value = _get(fields, _K_KEYS)
    if k_value is None:
        raise InputError(f"{src}: no camera matrix found (keys camera_matrix, K, or intrinsics: {{fx, fy, cx, cy}}); "
                         f"found keys {sorted(map(str, fields))[:12]}")
    K = _numbers(k_value, "camera_matrix", src)
    if K.size != 9:
        raise InputError(f"{src}: camera_matrix must hold 9 numbers (3x3), got {K.size}")
    d_value = _get(fields, _D_KEYS)
    dist = np.zeros(0) if d_value is None else _numbers(d_value, "distortion_coefficients", src).ravel()
    model = _get(fields, ("distortion_model",))
    if model is not None:
        model = str(model).strip().lower()
        if model not in ROS_MODELS:
            raise InputError(f"{src}: distortion_model {model!r} is not supported; use {' or '.join(ROS_MODELS)} "
                             "(OpenCV's pinhole model), e.g. recalibrate with handeye calibrate --images without "
                             "--intrinsics")
        if dist.size not in (0, ROS_MODELS[model]):
            raise InputError(f"{src}: distortion_model {model} has {ROS_MODELS[model]} coefficients, the file "
                             f"gives {dist.size}")
    width, height = _get(fields, _W_KEYS), _get(fields, _H_KEYS)
    size = None
    if width is not None and height is not None:
        try:
            size = (int(float(width)), int(float(height)))
        except (TypeError, ValueError):
            raise InputError(f"{src}: image_width and image_height must be numbers, got {width!r}, {height!r}") from None
    return _camera(K.reshape(3, 3), dist, size, src, _std(_get(fields, _STD_KEYS), "std_px", src))


def _std(value: Any, what: str, src: str) -> tuple[float, ...] | None:
    """The 1-sigma of fx, fy, cx, cy a file states: a mapping with those keys, or a list whose
    first four they are (OpenCV's stdDeviationsIntrinsics, a column of 18); None where absent."""
    if value is None:
        return None
    if isinstance(value, dict) and "data" not in value:
        lowered = {str(k).lower(): v for k, v in value.items()}
        missing = [k for k in _STD_ORDER if k not in lowered]
        if missing:
            raise InputError(f"{src}: {what} lacks {', '.join(missing)}; give the 1-sigma of fx, fy, cx, cy in pixels")
        return tuple(_scalar(lowered[k], f"{what}.{k}", src) for k in _STD_ORDER)
    values = _numbers(value, what, src).ravel()
    if values.size < 4:
        raise InputError(f"{src}: {what} must give the 1-sigma of fx, fy, cx, cy (pixels), got {values.size} numbers")
    return tuple(float(v) for v in values[:4])


def _camera(K: np.ndarray, dist: np.ndarray, size: tuple[int, int] | None, src: str,
            std: tuple[float, ...] | None = None) -> Camera:
    if np.all(dist == 0):
        dist = np.zeros(0)
    if not (K[2, 2] == 1 and K[1, 0] == 0 and K[2, 0] == 0 and K[2, 1] == 0):
        raise InputError(f"{src}: camera_matrix must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]], got {K.tolist()}")
    try:
        return Camera(K, dist, size, std)
    except InputError as exc:
        raise InputError(f"{src}: {exc}") from None


# ----------------------------------------------------------------------------- calibrating


@contextlib.contextmanager
def one_thread() -> Iterator[None]:
    """OpenCV on one thread for the block (its thread count restored after). OpenCV's parallel
    calibration adds the images' terms in whatever order its threads finish, so two runs on the
    same images differed in the 10th digit; on one thread a calibration is reproducible to the
    last digit (15 images of 100 points: 46 ms on one thread, 41 ms on two)."""
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(threads)


def calibrate_camera(detections: Sequence[PointsOfImage], image_size: tuple[int, int], *,
                     names: Sequence[str] | None = None, fix_k3: bool | None = None) -> CameraCalibration:
    """Intrinsics from the board points of several images (`cv2.calibrateCameraExtended`).

    detections: per image, ``image_points`` (n, 2) pixels and ``object_points`` (n, 3) on the
        board (any length unit: intrinsics do not depend on it).
    image_size: (width, height) in pixels.
    names: the images' names, for messages.
    fix_k3: fix k3 = 0; default: with fewer than `K3_MIN_VIEWS` images.

    Returns a `CameraCalibration`, which also unpacks as (camera, per-image RMS, overall RMS).
    """
    names = [str(n) for n in names] if names is not None else [f"image {i + 1}" for i in range(len(detections))]
    if len(detections) < MIN_VIEWS:
        raise InputError(f"calibrating the camera needs the board in at least {MIN_VIEWS} images, found it in "
                         f"{len(detections)}; give --intrinsics FILE or more images")
    width, height = (int(image_size[0]), int(image_size[1]))
    if width <= 0 or height <= 0:
        raise InputError(f"image size must be positive (width, height), got {image_size}")
    obj = [np.ascontiguousarray(d.object_points, dtype=np.float32).reshape(-1, 1, 3) for d in detections]  # OpenCV wants Point3f
    img = [np.ascontiguousarray(d.image_points, dtype=np.float32).reshape(-1, 1, 2) for d in detections]
    few = [n for n, o in zip(names, obj) if len(o) < 6]
    if few:
        raise InputError(f"calibrating the camera needs at least 6 board points per image; {few[0]} has fewer")
    fix_k3 = len(detections) < K3_MIN_VIEWS if fix_k3 is None else bool(fix_k3)
    flags = cv2.CALIB_FIX_K3 if fix_k3 else 0
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    try:
        with one_thread():
            rms, K, dist, rvecs, tvecs, std, _, per_view = cv2.calibrateCameraExtended(
                obj, img, (width, height), None, None, flags=flags, criteria=criteria)
    except cv2.error as exc:
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else "OpenCV error"
        raise InputError(f"calibrating the camera from {len(obj)} images failed ({reason}); give --intrinsics FILE "
                         "or images showing the board at more angles") from None
    camera = Camera(K, np.asarray(dist, dtype=float).ravel()[:5], (width, height))
    model = "k1, k2, p1, p2" + (" (k3 fixed at 0)" if fix_k3 else ", k3")
    poses = np.hstack([np.asarray(rvecs, dtype=float).reshape(-1, 3), np.asarray(tvecs, dtype=float).reshape(-1, 3)])
    return CameraCalibration(camera, np.asarray(per_view, dtype=float).ravel(), float(rms),
                             np.asarray(std, dtype=float).ravel()[:4], model, board_poses=poses)
