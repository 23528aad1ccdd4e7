"""Board rendering (handeye.vision.render): the texture's geometry, what the image shows where, the
blur / noise options and the poses it refuses. Detection accuracy on renders is in
test_vision_boards.py."""

from __future__ import annotations

import numpy as np
import pytest

from handeye.base.errors import InputError
from handeye.vision.boards import parse_board
from handeye.vision.observations import Camera
from handeye.vision.render import board_texture, project, render, view_pose

CAMERA = Camera(np.array([[500.0, 0, 160], [0, 500.0, 120], [0, 0, 1]]), np.zeros(0), (320, 240))
BOARD = parse_board("chessboard:5x4:20mm")


def sample(texture: np.ndarray, H: np.ndarray, x: float, y: float) -> int:
    u, v, w = H @ np.array([x, y, 1.0])
    return int(texture[int(np.rint(v / w)), int(np.rint(u / w))])


def test_texture_places_squares_circles_and_tags_where_the_board_frame_says():
    texture, H = board_texture(BOARD, 10.0)
    s = BOARD.spacing
    assert texture.dtype == np.uint8 and not texture.flags.writeable
    # squares: the one at x, y < 0 white, its neighbours black, the margin white
    assert sample(texture, H, -s / 2, -s / 2) == 255
    assert sample(texture, H, s / 2, -s / 2) == 0 and sample(texture, H, -s / 2, s / 2) == 0
    assert sample(texture, H, -1.5 * s, -1.5 * s) == 255
    grid = parse_board("circlegrid:4x3:20mm")
    texture, H = board_texture(grid, 10.0)
    radius = grid.diameter / 2
    assert sample(texture, H, 0, 0) == 0 and sample(texture, H, 1.5 * radius, 0) == 0  # the big dot
    assert sample(texture, H, 20, 0) == 0 and sample(texture, H, 20 + 1.5 * radius, 0) == 255
    april = parse_board("aprilgrid:2x2:30mm:0.3")
    texture, H = board_texture(april, 10.0)
    # tag outlines (2-bit black border) and the black corner squares in the gaps
    assert sample(texture, H, 1.0, 1.0) == 0 and sample(texture, H, -4.5, -4.5) == 0
    assert sample(texture, H, 15.0, -4.5) == 255


def test_aprilgrid_tags_are_drawn_as_kalibr_prints_them():
    """Kalibr's kalibr_create_target_pdf draws tag36h11 code c with data bit (i, j) (row i from the top)
    black where bit 35 - 6i - j of c is 0, inside a 2-bit black border. Codes of tags 0 and 1 as listed
    in that script."""
    april = parse_board("aprilgrid:2x1:100mm:0.3")
    texture, H = board_texture(april, 1.0)  # 10 texels per bit
    for tag, code in ((0, 0xD5D628584), (1, 0xD97F18B49)):
        x0 = tag * 1.3 * 100
        for i in range(6):
            for j in range(6):
                x, y = x0 + (2 + j + 0.5) * 10, 100 - (2 + i + 0.5) * 10  # bit centre, y up on the print
                expected = 255 if (code >> (35 - 6 * i - j)) & 1 else 0
                assert sample(texture, H, x, y) == expected, (tag, i, j)


def test_image_shows_the_board_at_the_projected_points_and_background_elsewhere():
    T = view_pose(BOARD, 400.0, tilt=(0.2, 0.1, 0.0))
    image = render(BOARD, CAMERA, T, background=90)
    assert image.shape == (240, 320) and image.dtype == np.uint8
    assert image[0, 0] == 90 and image[-1, -1] == 90
    corners = project(BOARD, CAMERA, T)
    # the square between corners 0, 1, 5, 6 is white (diagonal to the white one at x, y < 0), the next black
    white = corners[[0, 1, 5, 6]].mean(axis=0)
    assert image[int(np.rint(white[1])), int(np.rint(white[0]))] > 215
    black = corners[[1, 2, 6, 7]].mean(axis=0)
    assert image[int(np.rint(black[1])), int(np.rint(black[0]))] < 40


def test_noise_and_blur_are_what_was_asked_for():
    T = view_pose(BOARD, 400.0)
    clean = render(BOARD, CAMERA, T).astype(float)
    noisy = render(BOARD, CAMERA, T, noise=3.0, rng=np.random.default_rng(0)).astype(float)
    again = render(BOARD, CAMERA, T, noise=3.0, rng=np.random.default_rng(0)).astype(float)
    np.testing.assert_array_equal(noisy, again)
    flat = (clean > 20) & (clean < 235)  # away from clipping
    assert abs(np.std((noisy - clean)[flat]) - 3.0) < 0.3
    blurred = render(BOARD, CAMERA, T, blur=1.5).astype(float)
    assert np.abs(np.diff(blurred, axis=1)).max() < 0.6 * np.abs(np.diff(clean, axis=1)).max()
    assert abs(blurred.mean() - clean.mean()) < 1.0


def test_poses_and_cameras_it_cannot_draw_are_input_errors():
    T = view_pose(BOARD, 400.0)
    back = T.copy()
    back[:3, :3] = T[:3, :3] @ np.diag([1.0, -1.0, -1.0])  # turned over: the camera sees the back
    with pytest.raises(InputError, match="back of the chessboard"):
        render(BOARD, CAMERA, back)
    with pytest.raises(InputError, match="image size"):
        render(BOARD, Camera(CAMERA.K, CAMERA.dist), T)
    with pytest.raises(InputError, match="4x4"):
        render(BOARD, CAMERA, T[:3])
    with pytest.raises(InputError, match="blur"):
        render(BOARD, CAMERA, T, blur=-1.0)
