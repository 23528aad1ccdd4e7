"""``findChessboardCornersSB`` on the part of the image that holds the board: SB's cost follows the
image's area, not the board's -- with ``CALIB_CB_ACCURACY`` it upsamples the whole image 2x and
filters it at three scales (~4x SB's default flags) -- so on a padded crop around the board it
costs a fraction (the bench's 1.3 MP chessboard renders: crops of 11-36 % of the image, SB with
ACCURACY ~0.7x SB's default flags on the full image instead of ~4x).

`Region(gray, size)` is one image's search, `Region.find(flags)` runs SB with `flags` in it:

- the board is located once per image, from the image alone, by ``findChessboardCorners``
  (classic, FAST_CHECK; ~4 ms) on the image halved, else by SB's default flags on it (~25 ms): so
  a flag set's corners do not depend on which others run (an image set's plan keeps the corners
  of the full run);
- the crop is the located corners' bounding box with `MARGIN_SQUARES` of the board's largest
  square, at least `MARGIN_PX`, on every side, clipped to the image; SB runs on it and its
  corners are shifted back to full-image pixels;
- NORMALIZE_IMAGE: the full image's histogram is equalised first, as SB itself does, and the crop
  is cut from that and searched with the flag set's other flags (ACCURACY, or none for NORMALIZE
  alone): a crop's own histogram is another (SB with NORMALIZE | ACCURACY on the bare crop lay
  0.19-0.27 px from the truth instead of 0.06-0.08). NORMALIZE alone searched the full image
  until measured: 150-170 ms a call on a 1.3 MP render against 20-40 ms on the crop, so ~0.5 s of
  CPU on an image set's 4 probe images (~6 s for the 30 bench renders' detection in all), the
  corners as near the truth (figures below).

Every doubt falls back to the full image, so no board found before is lost: no location, a crop of
most of the image anyway (`FULL_FRACTION`), the board not found in the crop, or corners there that
do not lie on the located ones (`AGREE_SQUARES`). One exception: a flag set that misses the board
in the crop after another flag set found it there is not tried on the full image. On the real KUKA
chessboards (1.9 MP, the board filling much of the image) the NORMALIZE flag sets missed it in the
crop of 2 of 3 probe images and then on the full image as well, at 2-4 s an image, the probe's
largest cost; the kept corners and K of both KUKA sets are bit for bit those of the full-image fallback.

The corners are not those of the full image to the last bit: SB turns the image by 45 deg about
its centre and looks for corners on a grid anchored at its top-left pixel, so a crop resamples
differently. Measured (OpenCV 4.14), crop against full image:

- the 30 rendered 1.3 MP images of bench/images_speed.py (truth from the renderer): SB accuracy
  0.013 px RMS apart (0.09 px at most), 0.0262 px from the truth both (RMS over all corners);
  NORMALIZE | ACCURACY 0.015 apart, 0.063 both; SB's default flags 0.019 apart, 0.048 / 0.049;
  NORMALIZE alone 0.028 apart (0.25 at most), 0.0761 / 0.0748 (PnP residual 1.8 % larger, as
  NORMALIZE | ACCURACY's 1 %; never kept, so the kept corners, K and dist stayed bit-identical,
  in a full run and with the plan). The best-corner rule kept SB
  accuracy on 26 images instead of 25 (cornerSubPix on it on the others; the kept corners 0.0226
  px from the truth against 0.0223), fx, fy, cx, cy moved by 0.07, 0.07, -0.03, 0.04 px (their
  1-sigma 0.05-0.07 px; fx, fy and cy nearer the truth), the calibration RMS 0.01562 px against
  0.01556;
- 2 x 18 real 640 x 480 images (docs/boards.md): SB accuracy kept on every image as before, its
  corners 0.010-0.011 px RMS apart, PnP residual 0.3 % smaller; fx, fy, cx, cy within a quarter
  of their 1-sigma (1.6-2.6 px). NORMALIZE alone 0.070-0.071 px RMS apart (0.40 at most), as SB's
  default flags in the crop (0.066-0.073), its PnP residual 1.6 % larger / 2.6 % smaller; never
  kept, before or after: the kept corners, K and dist bit-identical.

The cornerSubPix candidate refined from SB's corners moves by 0.0003 px at most.
tests/vision/test_detection_speed.py checks the agreement, the truth and the fall-backs on renders.
"""

from __future__ import annotations

import cv2
import numpy as np

#: padding around the board's corners: SB's filters reach ~32 px beyond a corner (box filters up to
#: 32 px, then the feature map's own up to 32 px), and a board may be seen a little larger than
#: located. On the bench renders, against the full image: 1.0 square / 32 px left SB accuracy's
#: PnP residual 1.6 % smaller, NORMALIZE | ACCURACY's 1 % larger, the truth error the same (0.0262
#: px) and the crop 20 % of the image; 0.5 square / 32 px (17 %) NORMALIZE | ACCURACY's 6 % larger
#: (0.066 px from the truth against 0.063); 0.5 / 16 px SB accuracy 0.0274 px from the truth
MARGIN_SQUARES = 1.0
MARGIN_PX = 32
#: a crop larger than this fraction of the image saves little: the full image is searched
FULL_FRACTION = 0.7
#: the crop's corners must lie within this many squares of the located ones (nearest of them)
AGREE_SQUARES = 0.3
#: the image is halved to locate the board: classic findChessboardCorners then takes ~4 ms an image
#: of 1.3 MP (all 30 bench renders located), SB's default flags ~25 ms
LOCATE_SCALE = 0.5


class Region:
    """One image's chessboard search (module docstring): `find` runs SB with some flags; the board's
    location (`located`: its corners to about a pixel) and the crop (`box`: x0, y0, x1, y1; None
    for the full image) are settled on the first search, from the image alone."""

    def __init__(self, gray: np.ndarray, size: tuple[int, int]) -> None:
        self.gray, self.size = gray, size
        self.located: np.ndarray | None = None
        self.box: tuple[int, int, int, int] | None = None
        self._settled = False
        self._equalized: np.ndarray | None = None
        self._found_in_crop = False

    def find(self, flags: int) -> np.ndarray | None:
        """SB's corners (n, 2) of the (cols, rows) = `size` board with `flags`, in OpenCV's order and
        full-image pixels: searched in the crop, then in the full image if that fails; None when the
        board is not found."""
        if not self._settled:
            self._settled = True
            self.located = locate(self.gray, self.size)
            self.box = None if self.located is None else crop_box(self.located, self.size, self.gray.shape)
        if self.box is not None:
            x0, y0, x1, y1 = self.box
            image = self.gray
            if flags & cv2.CALIB_CB_NORMALIZE_IMAGE:  # what SB does first, on the whole image
                image, flags_in_crop = self._equalized_image(), flags & ~cv2.CALIB_CB_NORMALIZE_IMAGE
            else:
                flags_in_crop = flags
            found, corners = cv2.findChessboardCornersSB(np.ascontiguousarray(image[y0:y1, x0:x1]), self.size,
                                                         flags=flags_in_crop)
            if found:
                corners = corners.reshape(-1, 2).astype(np.float64) + (x0, y0)
                if _agree(corners, self.located, self.size):
                    self._found_in_crop = True
                    return corners
            elif self._found_in_crop:  # the board is in the crop (another flag set found it there): this
                return None  # flag set misses it, and on the full image too (measured below), at 3-10x the cost
        return self._full(flags)

    def _full(self, flags: int) -> np.ndarray | None:
        found, corners = cv2.findChessboardCornersSB(self.gray, self.size, flags=flags)
        return corners.reshape(-1, 2).astype(np.float64) if found else None

    def _equalized_image(self) -> np.ndarray:
        """The full image histogram-equalised (SB's NORMALIZE_IMAGE), computed once."""
        if self._equalized is None:
            self._equalized = cv2.equalizeHist(self.gray)
        return self._equalized


def locate(gray: np.ndarray, size: tuple[int, int]) -> np.ndarray | None:
    """The board's corners (n, 2) to about a pixel, from the image halved (`LOCATE_SCALE`): classic
    findChessboardCorners, else SB with its default flags; None when neither finds it."""
    small = cv2.resize(gray, None, fx=LOCATE_SCALE, fy=LOCATE_SCALE, interpolation=cv2.INTER_AREA)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK
    found, corners = cv2.findChessboardCorners(small, size, flags=flags)
    if not found:
        found, corners = cv2.findChessboardCornersSB(small, size, flags=0)
    if not found:
        return None
    # pixel centres: small pixel (u, v) covers full pixels [u / s, (u + 1) / s)
    return (corners.reshape(-1, 2).astype(np.float64) + 0.5) / LOCATE_SCALE - 0.5


def crop_box(corners: np.ndarray, size: tuple[int, int], shape: tuple[int, ...]) -> tuple[int, int, int, int] | None:
    """(x0, y0, x1, y1) of the crop around `corners` (grid order, `size` = (cols, rows)) in an
    image of `shape` (rows, cols): their bounding box, padded (`MARGIN_SQUARES`, `MARGIN_PX`) and
    clipped; None when it covers more than `FULL_FRACTION` of the image."""
    pad = max(MARGIN_SQUARES * largest_square(corners, size), MARGIN_PX)
    height, width = shape[:2]
    x0, y0 = np.floor(corners.min(axis=0) - pad).astype(int)
    x1, y1 = np.ceil(corners.max(axis=0) + pad).astype(int) + 1
    x0, y0, x1, y1 = max(int(x0), 0), max(int(y0), 0), min(int(x1), width), min(int(y1), height)
    if x1 <= x0 or y1 <= y0 or (x1 - x0) * (y1 - y0) > FULL_FRACTION * width * height:
        return None
    return x0, y0, x1, y1


def largest_square(corners: np.ndarray, size: tuple[int, int]) -> float:
    """The longest side (px) between neighbouring corners of the (rows, cols) grid `corners`."""
    grid = corners.reshape(size[1], size[0], 2)
    return float(max(np.linalg.norm(np.diff(grid, axis=1), axis=2).max(),
                     np.linalg.norm(np.diff(grid, axis=0), axis=2).max()))


def _agree(corners: np.ndarray, located: np.ndarray, size: tuple[int, int]) -> bool:
    """Every corner found in the crop lies near one of the located corners (module docstring)."""
    limit = AGREE_SQUARES * largest_square(located, size)
    distances = np.linalg.norm(corners[:, None, :] - located[None, :, :], axis=2)
    return bool(distances.min(axis=1).max() < limit)
