"""Synthetic images of a calibration board seen by a camera, for end-to-end tests without data.

`render(board, camera, T_cam_target)` draws what a camera with intrinsics K, distortion `dist` and
image size sees of the board at pose T_cam_target: every output pixel is traced back through the
lens (``cv2.undistortPointsIter``), intersected with the board's plane z = 0 (a homography) and
looked up in a high-resolution texture of the printed board (`board_texture`) with ``cv2.remap``. The
image is supersampled (`SUPERSAMPLING` x `SUPERSAMPLING` rays per pixel, averaged) so edges are
area-sampled rather than aliased, then optionally blurred and noised.

`render_boards(scene, camera)` draws several boards (board, T_cam_target) in one image, nearer ones
over farther ones: the targets of a cell of several cameras and targets.

The truth is exact by construction: the board's points project to
``cv2.projectPoints(board.object_points(), rvec, tvec, K, dist)`` (pixel centres at integer
coordinates, OpenCV's convention). Textures and the per-camera ray grid are cached: rendering many
poses of one board with one camera costs one remap each.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import cv2
import numpy as np

from handeye.base.errors import InputError
from handeye.vision.boards import BIG_DOT_RATIO, Board
from handeye.vision.observations import Camera

#: rays per pixel along each axis
SUPERSAMPLING = 3
#: texels per image pixel where the board is nearest, and the Gaussian (sigma, texels) the texture
#: is pre-filtered with: together with the supersampling this keeps edges free of aliasing (corner
#: errors of detectors on renders halve compared with a sharp texture at one texel per ray)
TEXELS_PER_PIXEL = 1.5
TEXTURE_BLUR = 1.0
#: largest texture side in pixels (memory / speed bound); finer boards are drawn coarser
MAX_TEXTURE_SIDE = 8000
#: fixed-point bits of subpixel circle centres (cv2.circle's `shift`)
_SHIFT = 8
#: supersampled rows traced at once
_CHUNK_ROWS = 256


def render(board: Board, camera: Camera, T_cam_target: np.ndarray, *, blur: float = 0.0, noise: float = 0.0,
           rng: np.random.Generator | None = None, background: int = 128) -> np.ndarray:
    """A uint8 grayscale image (height, width) = camera.size of `board` at pose `T_cam_target` (4x4,
    translations in board.unit): white margin around the printed pattern, `background` grey elsewhere,
    then a Gaussian blur of `blur` pixels (sigma) and Gaussian noise of `noise` grey levels (sigma),
    clipped to 0..255. `rng` draws the noise (default: a fresh, unseeded generator)."""
    return render_boards([(board, T_cam_target)], camera, blur=blur, noise=noise, rng=rng, background=background)


def render_boards(scene: Sequence[tuple[Board, np.ndarray]], camera: Camera, *, blur: float = 0.0,
                  noise: float = 0.0, rng: np.random.Generator | None = None, background: int = 128) -> np.ndarray:
    """As `render`, with several boards in one image (a cell's targets seen together): `scene` holds
    (board, T_cam_target) pairs; each board (with its white margin) is drawn over the ones farther
    from the camera, so a nearer board hides what lies behind it."""
    if camera.size is None:
        raise InputError("render needs the camera's image size; give Camera(K, dist, size=(width, height))")
    if blur < 0 or noise < 0 or not 0 <= background <= 255:
        raise InputError(f"render: blur and noise must be >= 0 and background in 0..255, got {blur}, {noise}, "
                         f"{background}")
    width, height = camera.size
    rays = _camera_rays(camera.K.tobytes(), camera.dist.tobytes(), width, height)
    fine = np.full(rays.shape[:2], float(background), np.float32)
    poses = [np.asarray(T, dtype=float) for _, T in scene]
    for T in poses:
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise InputError(f"T_cam_target must be a finite 4x4 pose, got shape {T.shape}")
    order = sorted(range(len(poses)), key=lambda k: -float(poses[k][2, 3]))  # farthest first
    for n, k in enumerate(order):  # the first layer over the plain background exactly as one board alone
        _draw_layer(fine, rays, scene[k][0], camera, poses[k], float(background) if n == 0 else None)
    image = cv2.resize(fine, (width, height), interpolation=cv2.INTER_AREA)
    if blur > 0:
        image = cv2.GaussianBlur(image, (0, 0), sigmaX=float(blur), sigmaY=float(blur))
    if noise > 0:
        rng = np.random.default_rng() if rng is None else rng
        image = image + rng.normal(0.0, float(noise), image.shape).astype(np.float32)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def _draw_layer(fine: np.ndarray, rays: np.ndarray, board: Board, camera: Camera, T: np.ndarray,
                background: float | None) -> None:
    """Draw `board` at pose T into the supersampled image `fine` (in place). Over a plain
    `background` grey: the texture sampled with that grey beyond its edge. Over other boards
    (background None): the texture's share of each ray's bilinear sample (its coverage, 0..1 in
    the last texel beyond the edge) over what is there."""
    camera_height = float(-(T[:3, :3].T @ T[:3, 3])[2])  # camera centre's z in the board frame
    if abs(camera_height) < 1e-9 * float(np.linalg.norm(T[:3, 3]) + board.spacing):
        raise InputError("the camera centre lies in the board's plane at this pose, so it sees the board edge-on")
    if _sees_back(board, T):
        raise InputError(f"the camera sees the back of the {board.kind} at this pose; its printed face is on the "
                         f"board's {'+' if _face_up(board) else '-'}z side (docs/boards.md)")
    ppu = _texture_resolution(board, camera, T)
    texture, H_texture_board = _prefiltered_texture(board, ppu)
    # normalised ray (x, y, 1) -> board plane: inverse of [r1 r2 t], then board -> texture
    H = H_texture_board @ np.linalg.inv(np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]))
    rows, cols = texture.shape
    for top in range(0, rays.shape[0], _CHUNK_ROWS):  # in bands of rows: bounded temporaries
        band = rays[top:top + _CHUNK_ROWS].astype(np.float64)
        map_x, map_y = _texture_coordinates(band[..., 0], band[..., 1], H, T)
        if background is not None:
            fine[top:top + _CHUNK_ROWS] = cv2.remap(texture, map_x, map_y, cv2.INTER_LINEAR,
                                                    borderMode=cv2.BORDER_CONSTANT, borderValue=background)
            continue
        drawn = cv2.remap(texture, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
        cover = (np.clip(np.minimum(map_x + 1, cols - map_x), 0, 1) * np.clip(np.minimum(map_y + 1, rows - map_y), 0, 1))
        band = fine[top:top + _CHUNK_ROWS]
        band[...] = drawn + (1.0 - cover) * band


def _texture_coordinates(x: np.ndarray, y: np.ndarray, H: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Texel coordinates (float32 maps for cv2.remap) where the rays (x, y, 1) meet the board; rays
    that meet its plane behind the camera, or never, get a point far outside the texture."""
    w = H[2, 0] * x + H[2, 1] * y + H[2, 2]
    # a ray meets the plane n.(p - t) = 0 at depth n.t / n.(x, y, 1): it must be positive
    normal, origin = T[:3, 2], T[:3, 3]
    in_front = (normal @ origin) * (normal[0] * x + normal[1] * y + normal[2]) > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        map_x = (H[0, 0] * x + H[0, 1] * y + H[0, 2]) / w
        map_y = (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / w
    outside = ~in_front | ~np.isfinite(map_x) | ~np.isfinite(map_y)
    map_x[outside], map_y[outside] = -1e4, -1e4
    limit = 3e4  # remap's coordinates must stay representable
    return (np.clip(map_x, -limit, limit).astype(np.float32), np.clip(map_y, -limit, limit).astype(np.float32))


def view_pose(board: Board, distance: float, *, tilt: tuple[float, float, float] = (0.0, 0.0, 0.0),
              roll: float = 0.0) -> np.ndarray:
    """T_cam_target (4x4) that puts the centre of the board's pattern `distance` (board.unit) ahead
    on the optical axis with its printed face toward the camera: turned `roll` radians about its own
    normal, then tilted by the rotation vector `tilt` (radians) about its centre. roll = pi shows the
    board upside down."""
    from scipy.spatial.transform import Rotation

    x0, y0, x1, y1 = board.extent()
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    face = Rotation.from_euler("x", np.pi) if _face_up(board) else Rotation.identity()
    R = Rotation.from_rotvec(np.asarray(tilt, dtype=float)) * face * Rotation.from_euler("z", roll)
    T = np.eye(4)
    T[:3, :3] = R.as_matrix()
    T[:3, 3] = np.array([0.0, 0.0, float(distance)]) - R.apply(centre)
    return T


def project(board: Board, camera: Camera, T_cam_target: np.ndarray) -> np.ndarray:
    """(N, 2) pixels of every board point at pose T_cam_target: the truth a render is drawn to."""
    T = np.asarray(T_cam_target, dtype=float)
    rvec, _ = cv2.Rodrigues(T[:3, :3])
    points, _ = cv2.projectPoints(board.object_points(), rvec, T[:3, 3], camera.K, camera.dist)
    return points.reshape(-1, 2)


def _face_up(board: Board) -> bool:
    """True when the printed face looks along the board's +z (y up on the print: circlegrid and
    aprilgrid); OpenCV's boards (y down on the print) face -z."""
    return board.kind in ("circlegrid", "aprilgrid")


def printed_normal(board: Board) -> np.ndarray:
    """The unit normal out of the board's printed face, in its frame: +z for circlegrid and
    aprilgrid, -z for OpenCV's boards (`_face_up`)."""
    return np.array([0.0, 0.0, 1.0 if _face_up(board) else -1.0])


def _sees_back(board: Board, T: np.ndarray) -> bool:
    """Whether the camera centre lies on the unprinted side of the board's plane."""
    camera_in_board = -T[:3, :3].T @ T[:3, 3]
    return bool(camera_in_board[2] > 0) != _face_up(board)


@functools.lru_cache(maxsize=2)
def _camera_rays(K: bytes, dist: bytes, width: int, height: int) -> np.ndarray:
    """(SS*height, SS*width, 2) float32 normalised image coordinates of the supersampled pixel grid
    (float32: 1e-7 relative, far below a pixel; half the memory of the cache)."""
    K_ = np.frombuffer(K).reshape(3, 3)
    dist_ = np.frombuffer(dist)
    ss = SUPERSAMPLING
    offsets = (np.arange(ss) + 0.5) / ss - 0.5
    u = (np.arange(width)[:, None] + offsets[None, :]).ravel()
    v = (np.arange(height)[:, None] + offsets[None, :]).ravel()
    uu, vv = np.meshgrid(u, v)
    pixels = np.stack([uu, vv], axis=-1).reshape(-1, 1, 2)
    if dist_.size == 0 or not np.any(dist_):
        x = (pixels[..., 0] - K_[0, 2] - K_[0, 1] * (pixels[..., 1] - K_[1, 2]) / K_[1, 1]) / K_[0, 0]
        y = (pixels[..., 1] - K_[1, 2]) / K_[1, 1]
        rays = np.concatenate([x[..., None], y[..., None]], axis=-1)
    else:
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
        rays = cv2.undistortPointsIter(pixels, K_, dist_, None, None, criteria)
    rays = rays.reshape(len(v), len(u), 2).astype(np.float32)
    rays.setflags(write=False)
    return rays


def _texture_resolution(board: Board, camera: Camera, T: np.ndarray) -> float:
    """Texture pixels per board unit: TEXELS_PER_PIXEL texels per image pixel where the board is nearest,
    on the lattice `_pixel_lattice` allows, at most MAX_TEXTURE_SIDE texels across."""
    x0, y0, x1, y1 = board.extent()
    corners = np.array([[x0, y0, 0, 1], [x1, y0, 0, 1], [x1, y1, 0, 1], [x0, y1, 0, 1]], dtype=float)
    depth = max(float(np.min((corners @ T.T)[:, 2])), 1e-9 * board.spacing)
    wanted = TEXELS_PER_PIXEL * max(camera.K[0, 0], camera.K[1, 1]) / depth
    side = max(x1 - x0, y1 - y0) + 2 * _margin(board)
    return _pixel_lattice(board, min(wanted, MAX_TEXTURE_SIDE / side))


def _pixel_lattice(board: Board, ppu: float) -> float:
    """The resolution nearest above `ppu` at which the board's squares, tag bits and gaps are whole
    texels (so straight edges sit exactly on texel boundaries); circles are drawn subpixel anyway."""
    step = 10 if board.kind == "aprilgrid" else 1  # an aprilgrid tag is 10 bits across (2-bit border)
    if board.kind == "aprilgrid":
        for k in range(1, 101):  # gap = tag_spacing * tag: whole texels when tag_spacing * 10 * k is
            if abs(board.tag_spacing * 10 * k - round(board.tag_spacing * 10 * k)) < 1e-6:
                step = 10 * k
                break
    per_spacing = max(step, step * np.ceil(ppu * board.spacing / step))
    return float(per_spacing / board.spacing)


def _margin(board: Board) -> float:
    """White margin around the printed pattern, in board units (one square / spacing)."""
    return float(board.spacing)


@functools.lru_cache(maxsize=4)
def _prefiltered_texture(board: Board, px_per_unit: float) -> tuple[np.ndarray, np.ndarray]:
    """board_texture blurred by TEXTURE_BLUR texels (the anti-aliasing pre-filter), cached."""
    texture, H = board_texture(board, px_per_unit)
    blurred = cv2.GaussianBlur(texture, (0, 0), TEXTURE_BLUR)
    blurred.setflags(write=False)
    return blurred, H


@functools.lru_cache(maxsize=4)
def board_texture(board: Board, px_per_unit: float) -> tuple[np.ndarray, np.ndarray]:
    """(texture, H_texture_board): a uint8 image of the printed board (black on white, with a white
    margin of one spacing) at `px_per_unit` texels per board unit, and the 3x3 map from board-plane
    (x, y, 1) to texel coordinates (texel centres at integers). Read-only; cached."""
    x0, y0, x1, y1 = board.extent()
    margin = _margin(board)
    left, top = x0 - margin, y0 - margin
    width = int(np.ceil((x1 - x0 + 2 * margin) * px_per_unit - 1e-9))
    height = int(np.ceil((y1 - y0 + 2 * margin) * px_per_unit - 1e-9))
    if max(width, height) > 4 * MAX_TEXTURE_SIDE:
        raise InputError(f"board texture of {width}x{height} texels is too large; use fewer pixels per unit")
    # y down on the print (OpenCV's boards) or up (circlegrid, aprilgrid: origin bottom-left, z out)
    if _face_up(board):
        H = np.array([[px_per_unit, 0, -left * px_per_unit - 0.5],
                      [0, -px_per_unit, (y1 + margin) * px_per_unit - 0.5], [0, 0, 1]])
    else:
        H = np.array([[px_per_unit, 0, -left * px_per_unit - 0.5],
                      [0, px_per_unit, -top * px_per_unit - 0.5], [0, 0, 1]])
    texture = np.full((height, width), 255, np.uint8)
    draw = {"chessboard": _draw_chessboard, "charuco": _draw_charuco, "circles": _draw_circles,
            "circlegrid": _draw_circles, "aprilgrid": _draw_aprilgrid}[board.kind]
    draw(texture, board, H, px_per_unit)
    texture.setflags(write=False)
    H.setflags(write=False)
    return texture, H


def _texel(H: np.ndarray, x: float, y: float) -> tuple[float, float]:
    u, v, w = H @ np.array([x, y, 1.0])
    return u / w, v / w


def _fill_rect(texture: np.ndarray, H: np.ndarray, x0: float, y0: float, x1: float, y1: float) -> None:
    """Black rectangle with board corners (x0, y0), (x1, y1): texels whose centres lie inside."""
    (ua, va), (ub, vb) = _texel(H, x0, y0), _texel(H, x1, y1)
    c0, c1 = int(np.ceil(min(ua, ub) - 1e-6)), int(np.floor(max(ua, ub) + 1e-6))
    r0, r1 = int(np.ceil(min(va, vb) - 1e-6)), int(np.floor(max(va, vb) + 1e-6))
    texture[max(r0, 0):max(r1 + 1, 0), max(c0, 0):max(c1 + 1, 0)] = 0


def _draw_chessboard(texture: np.ndarray, board: Board, H: np.ndarray, ppu: float) -> None:
    # (cols + 1) x (rows + 1) squares; the one at x, y < 0 white: then findChessboardCornersSB numbers an
    # unambiguous board (cols + rows odd) from the origin of object_points, whatever the view
    s = board.spacing
    for r in range(board.rows + 1):
        for c in range(board.cols + 1):
            if (r + c) % 2 == 1:
                _fill_rect(texture, H, (c - 1) * s, (r - 1) * s, c * s, r * s)


def _draw_charuco(texture: np.ndarray, board: Board, H: np.ndarray, ppu: float) -> None:
    from handeye.vision.detect import (
        charuco_board,  # one place builds OpenCV's board object
    )

    cv_board = charuco_board(board)
    square = int(np.rint(board.spacing * ppu))
    image = cv_board.generateImage((board.cols * square, board.rows * square), marginSize=0, borderBits=1)
    u, v = _texel(H, 0.0, 0.0)
    c, r = int(np.rint(u + 0.5)), int(np.rint(v + 0.5))
    texture[r:r + image.shape[0], c:c + image.shape[1]] = image


def _draw_circles(texture: np.ndarray, board: Board, H: np.ndarray, ppu: float) -> None:
    scale = 1 << _SHIFT
    for i, (x, y, _) in enumerate(board.object_points()):
        radius = board.diameter / 2 * (BIG_DOT_RATIO if board.kind == "circlegrid" and i == 0 else 1.0)
        u, v = _texel(H, x, y)
        cv2.circle(texture, (int(np.rint(u * scale)), int(np.rint(v * scale))), int(np.rint(radius * ppu * scale)), 0,
                   thickness=-1, lineType=cv2.LINE_AA, shift=_SHIFT)


def _draw_aprilgrid(texture: np.ndarray, board: Board, H: np.ndarray, ppu: float) -> None:
    """Kalibr's target: tag36h11 tags with a 2-bit black border, ids row-major from the bottom-left,
    each turned 180 deg from OpenCV's drawing of the marker (as kalibr_create_target_pdf draws it,
    handeye.vision.aprilgrid), and a black square of side gap at every tag corner."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    s, gap = board.spacing, board.tag_spacing * board.spacing
    side = int(np.rint(s * ppu))
    corners = board.object_points().reshape(-1, 4, 3)
    for tag, quad in enumerate(corners):
        x0, y0 = quad[0, :2]
        for cx, cy in ((x0 - gap, y0 - gap), (x0 + s, y0 - gap), (x0 + s, y0 + s), (x0 - gap, y0 + s)):
            _fill_rect(texture, H, cx, cy, cx + gap, cy + gap)
        marker = np.rot90(cv2.aruco.generateImageMarker(dictionary, board.first_id + tag, side, borderBits=2), 2)
        u, v = _texel(H, x0, y0 + s)  # the tag's top-left on the print
        c, r = int(np.rint(u + 0.5)), int(np.rint(v + 0.5))
        texture[r:r + side, c:c + side] = marker
