"""Calibration boards: what a board is (kind, counts, sizes, unit) and where its points lie.

A `Board` describes a printed target well enough to detect it (`handeye.vision.detect`), to render it
(`handeye.vision.render`) and to give the board-frame coordinates of every point a detector reports
(`Board.object_points`, id i = row i). The five kinds, their counts and frames (docs/boards.md):

- ``chessboard``: cols x rows *inner* corners (OpenCV's patternSize), square side `spacing`; id
  r*cols + c at (c, r) * spacing. Symmetric boards (cols + rows even) can be reported in two orders
  180 deg apart: `orientation_ambiguous`.
- ``charuco``: cols x rows *squares* (OpenCV's CharucoBoard size), square `spacing`, marker `marker`,
  ArUco `dictionary`; ids are ChArUco corner ids ((cols-1) x (rows-1) inner corners, OpenCV's frame).
- ``circles``: OpenCV's asymmetric circle grid, cols circles per row, rows (odd) rows; id r*cols + c
  at ((2c + r mod 2) * spacing, r * spacing) (OpenCV's sample convention).
- ``circlegrid``: symmetric grid with one larger origin dot (ROS-Industrial's modified circle grid);
  id r*cols + c at (c, r) * spacing with the big dot id 0, x along its row, y away from it, z out of
  the printed face.
- ``aprilgrid``: Kalibr's grid of cols x rows tag36h11 tags of side `spacing`, gap `tag_spacing` *
  spacing; corner id 4 * tag + k, k = 0..3 the tag's bottom-left, bottom-right, top-right, top-left.

`parse_board` reads the one-line spec (``chessboard:9x6:25mm``) or a YAML/JSON file with the same
fields. Lengths stay in the board's unit; `in_unit` converts.

Several boards of a cell may be seen in one image (`handeye.vision.board_set`): ChArUco boards and
AprilGrids then carry disjoint marker ids, set by `first_id` (OpenCV's ``CharucoBoard(..., ids)``:
the board's markers are ids first_id, first_id + 1, ...; an AprilGrid's tags likewise), written
``:first=N`` at the end of a spec.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.base.vocabulary import LENGTH_UNITS, METRES_PER
from handeye.io.input_files import load_json, load_yaml, number

KINDS = ("chessboard", "charuco", "circles", "circlegrid", "aprilgrid")
UNITS = {unit: METRES_PER[unit] for unit in LENGTH_UNITS}

#: the spec syntax per kind, with an example, quoted in every parse error
SYNTAX = {
    "chessboard": "chessboard:COLSxROWS:SQUARE (inner corners), e.g. chessboard:9x6:25mm",
    "charuco": "charuco:COLSxROWS:SQUARE:MARKER:DICT[:legacy][:first=N] (squares), e.g. "
               "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250",
    "circles": "circles:COLSxROWS:SPACING[:DIAMETER] (asymmetric grid), e.g. circles:4x11:20mm",
    "circlegrid": "circlegrid:COLSxROWS:SPACING[:DIAMETER] (big origin dot), e.g. circlegrid:10x10:25.4mm",
    "aprilgrid": "aprilgrid:COLSxROWS:TAGSIZE:SPACING_RATIO[:first=N] (tags), e.g. aprilgrid:6x6:88mm:0.3",
}
SYNTAX_LINE = "; ".join(SYNTAX.values()) + "; or a YAML/JSON file with these fields (docs/boards.md)"

#: ArUco dictionaries a ChArUco board may use (OpenCV's names)
ARUCO_DICTIONARIES = tuple(f"DICT_{b}X{b}_{n}" for b in (4, 5, 6, 7) for n in (50, 100, 250, 1000)) + (
    "DICT_ARUCO_ORIGINAL", "DICT_ARUCO_MIP_36H12", "DICT_APRILTAG_16H5", "DICT_APRILTAG_25H9",
    "DICT_APRILTAG_36H10", "DICT_APRILTAG_36H11")
APRILGRID_DICTIONARY = "DICT_APRILTAG_36H11"
#: circle diameter / spacing when the spec gives none: ROS-Industrial's target generator (10 mm dots,
#: 25 mm apart) for circlegrid, OpenCV's asymmetric pattern proportions for circles
DEFAULT_DIAMETER_RATIO = {"circlegrid": 0.4, "circles": 0.5}
#: the origin dot of a circlegrid is this many times the others' diameter (ROS-Industrial's generator)
BIG_DOT_RATIO = 2.0


@dataclasses.dataclass(frozen=True)
class Board:
    """A calibration board. `cols`/`rows` count as OpenCV does for the kind (module docstring),
    `spacing` is the square side / circle spacing / tag side in `unit` ("mm" or "m").

    Kind-specific fields: `marker` (ChArUco marker side), `dictionary` (ArUco dictionary name of a
    ChArUco board; DICT_APRILTAG_36H11 for an aprilgrid), `legacy` (ChArUco boards drawn by OpenCV
    < 4.6 with an even number of rows: OpenCV's legacy pattern), `tag_spacing` (aprilgrid gap / tag
    side), `diameter` (circle diameter of circles / circlegrid boards, for rendering and blob sizes),
    `first_id` (ChArUco, aprilgrid: the id of the board's first marker / tag, the others following
    in order; 0 by default, other values let several boards share an image).
    """

    kind: str
    cols: int
    rows: int
    spacing: float
    unit: str = "mm"
    marker: float | None = None
    dictionary: str | None = None
    legacy: bool = False
    tag_spacing: float | None = None
    diameter: float | None = None
    first_id: int = 0

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InputError(f"unknown board kind {self.kind!r}; use one of: {SYNTAX_LINE}")
        syntax = SYNTAX[self.kind]
        if not isinstance(self.unit, str) or self.unit not in UNITS:
            raise InputError(f"board unit must be 'mm' or 'm', got {self.unit!r}; syntax: {syntax}")
        for name in ("cols", "rows"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < _min_count(self.kind):
                raise InputError(f"board {name} must be a whole number >= {_min_count(self.kind)}, got "
                                 f"{value!r}; syntax: {syntax}")
            object.__setattr__(self, name, int(value))
        _positive(self, "spacing", syntax)
        if self.kind == "circles" and self.rows % 2 == 0:
            raise InputError(f"an asymmetric circle grid needs an odd number of rows (got {self.rows}): with an even "
                             f"number it looks the same turned 180 deg; syntax: {syntax}")
        defaults = {"charuco": {"dictionary": "DICT_6X6_250"}, "aprilgrid": {"dictionary": APRILGRID_DICTIONARY,
                                                                             "tag_spacing": 0.3}}
        for name, value in defaults.get(self.kind, {}).items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, value)
        check = _KIND_CHECKS.get(self.kind)
        if check is not None:
            check(self, syntax)
        if not isinstance(self.legacy, (bool, np.bool_)):
            raise InputError(f"board field 'legacy' must be true or false, got {self.legacy!r}")
        object.__setattr__(self, "legacy", bool(self.legacy))
        for name in ("marker", "legacy", "tag_spacing", "diameter"):
            if name not in _FIELDS_OF[self.kind] and getattr(self, name) not in (None, False):
                raise InputError(f"board field {name!r} does not apply to a {self.kind}; syntax: {syntax}")
        if self.kind != "charuco" and self.kind != "aprilgrid" and self.dictionary is not None:
            raise InputError(f"board field 'dictionary' does not apply to a {self.kind}; syntax: {syntax}")
        _check_first_id(self, syntax)

    # -- geometry ------------------------------------------------------------------------------
    @property
    def orientation_ambiguous(self) -> bool:
        """True when two images of this board can number its points in orders 180 deg apart: a
        chessboard with cols + rows even (colours symmetric under a half turn; square boards are
        also 90 deg symmetric). Every other kind fixes its frame from the pattern itself."""
        return self.kind == "chessboard" and (self.cols + self.rows) % 2 == 0

    @property
    def marker_ids(self) -> range:
        """The marker (ChArUco) or tag (aprilgrid) ids the board carries; empty for the other kinds."""
        if self.kind == "charuco":
            return range(self.first_id, self.first_id + self.cols * self.rows // 2)
        if self.kind == "aprilgrid":
            return range(self.first_id, self.first_id + self.cols * self.rows)
        return range(0)

    @property
    def point_count(self) -> int:
        """How many ids the board has (rows of `object_points`)."""
        if self.kind == "charuco":
            return (self.cols - 1) * (self.rows - 1)
        if self.kind == "aprilgrid":
            return 4 * self.cols * self.rows
        return self.cols * self.rows

    def object_points(self) -> np.ndarray:
        """(N, 3) float64 board-frame coordinates (z = 0) of ids 0..N-1, in `self.unit`."""
        s = float(self.spacing)
        r, c = np.divmod(np.arange(self.cols * self.rows), self.cols)
        if self.kind in ("chessboard", "circlegrid"):
            xy = np.column_stack([c * s, r * s])
        elif self.kind == "circles":
            xy = np.column_stack([(2 * c + r % 2) * s, r * s])
        elif self.kind == "charuco":
            r, c = np.divmod(np.arange(self.point_count), self.cols - 1)
            xy = np.column_stack([(c + 1) * s, (r + 1) * s])
        else:  # aprilgrid: tag t at column t % cols, row t // cols; corners BL, BR, TR, TL
            pitch = (1.0 + float(self.tag_spacing)) * s
            corner = np.array([[0.0, 0.0], [s, 0.0], [s, s], [0.0, s]])
            xy = (np.column_stack([c * pitch, r * pitch])[:, None, :] + corner[None]).reshape(-1, 2)
        return np.column_stack([xy, np.zeros(len(xy))]).astype(np.float64)

    def extent(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) of the printed pattern in the board frame (without the white
        margin a printed board has around it), in `self.unit`."""
        s = float(self.spacing)
        points = self.object_points()[:, :2]
        lo, hi = points.min(axis=0), points.max(axis=0)
        if self.kind == "chessboard":
            lo, hi = lo - s, hi + s
        elif self.kind == "charuco":
            lo, hi = np.zeros(2), np.array([self.cols * s, self.rows * s])
        elif self.kind in ("circles", "circlegrid"):
            radius = float(self.diameter) / 2 * (BIG_DOT_RATIO if self.kind == "circlegrid" else 1.0)
            lo, hi = lo - radius, hi + radius
        else:  # the corner squares of Kalibr's grid stick out by one gap
            gap = float(self.tag_spacing) * s
            lo, hi = lo - gap, hi + gap
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])

    # -- units and text -------------------------------------------------------------------------
    def in_unit(self, unit: str) -> Board:
        """The same board with its lengths in `unit` ("mm" or "m")."""
        if not isinstance(unit, str) or unit not in UNITS:
            raise InputError(f"board unit must be 'mm' or 'm', got {unit!r}")
        f = UNITS[self.unit] / UNITS[unit]
        scale = {name: getattr(self, name) * f for name in ("spacing", "marker", "diameter")
                 if getattr(self, name) is not None}
        return dataclasses.replace(self, unit=unit, **scale)

    def describe(self) -> str:
        """One line for people, e.g. "chessboard 9x6 inner corners, 25 mm squares"."""
        s, u = f"{self.spacing:g}", self.unit
        if self.kind == "chessboard":
            return f"chessboard {self.cols}x{self.rows} inner corners, {s} {u} squares"
        if self.kind == "charuco":
            legacy = ", legacy pattern" if self.legacy else ""
            return (f"ChArUco {self.cols}x{self.rows} squares, {s} {u} squares, {self.marker:g} {u} markers, "
                    f"{self.dictionary}{legacy}{self._ids_text()}")
        if self.kind == "circles":
            return (f"asymmetric circle grid {self.cols}x{self.rows} circles, {s} {u} spacing, "
                    f"{self.diameter:g} {u} circles")
        if self.kind == "circlegrid":
            return (f"circle grid {self.cols}x{self.rows} with a big origin dot, {s} {u} spacing, "
                    f"{self.diameter:g} {u} dots")
        return (f"AprilGrid {self.cols}x{self.rows} tag36h11 tags, {s} {u} tags, spacing ratio {self.tag_spacing:g}"
                f"{self._ids_text()}")

    def _ids_text(self) -> str:
        ids = self.marker_ids
        return f", ids {ids.start}..{ids.stop - 1}" if self.first_id else ""

    def spec(self) -> str:
        """The one-line spec `parse_board` reads back into this board."""
        size = f"{self.cols}x{self.rows}:{self.spacing:g}{self.unit}"
        first = f":first={self.first_id}" if self.first_id else ""
        if self.kind == "charuco":
            return (f"charuco:{size}:{self.marker:g}{self.unit}:{self.dictionary}" + (":legacy" if self.legacy else "")
                    + first)
        if self.kind in ("circles", "circlegrid"):
            return f"{self.kind}:{size}:{self.diameter:g}{self.unit}"
        if self.kind == "aprilgrid":
            return f"aprilgrid:{size}:{self.tag_spacing:g}{first}"
        return f"chessboard:{size}"


def _check_charuco(board: Board, syntax: str) -> None:
    """Marker smaller than the square; a dictionary OpenCV knows (upper-cased)."""
    if board.marker is None:
        raise InputError(f"a ChArUco board needs its marker size; syntax: {syntax}")
    _positive(board, "marker", syntax)
    if board.marker >= board.spacing:
        raise InputError(f"ChArUco marker {board.marker:g} {board.unit} must be smaller than the square "
                         f"{board.spacing:g} {board.unit}; syntax: {syntax}")
    if str(board.dictionary).upper() not in ARUCO_DICTIONARIES:
        raise InputError(f"unknown ArUco dictionary {board.dictionary!r}; use one of "
                         f"{', '.join(ARUCO_DICTIONARIES)}; syntax: {syntax}")
    object.__setattr__(board, "dictionary", str(board.dictionary).upper())


def _check_aprilgrid(board: Board, syntax: str) -> None:
    """Spacing ratio in (0, 1]; tag36h11 only."""
    _positive(board, "tag_spacing", syntax)
    if board.tag_spacing > 1.0:
        raise InputError(f"aprilgrid spacing ratio must be in (0, 1] (gap / tag size, Kalibr's "
                         f"tagSpacing), got {board.tag_spacing:g}; syntax: {syntax}")
    if str(board.dictionary).upper() != APRILGRID_DICTIONARY:
        raise InputError(f"an aprilgrid uses {APRILGRID_DICTIONARY} (Kalibr's tag36h11), got "
                         f"{board.dictionary!r}")


def _check_circles(board: Board, syntax: str) -> None:
    """Default diameter; circles that do not touch their nearest neighbours."""
    if board.diameter is None:
        object.__setattr__(board, "diameter", DEFAULT_DIAMETER_RATIO[board.kind] * float(board.spacing))
    _positive(board, "diameter", syntax)
    # nearest centres: spacing apart (the big dot's radius is BIG_DOT_RATIO times), or
    # sqrt(2) * spacing on an asymmetric grid
    limit = (board.spacing / ((BIG_DOT_RATIO + 1) / 2) if board.kind == "circlegrid"
             else board.spacing * 2 ** 0.5)
    if board.diameter >= limit:
        raise InputError(f"circle diameter {board.diameter:g} {board.unit} is too large for spacing "
                         f"{board.spacing:g} {board.unit} (circles would touch); syntax: {syntax}")


def _check_first_id(board: Board, syntax: str) -> None:
    """`first_id`: a whole number >= 0, only for ChArUco and aprilgrid boards, whose ids stay in
    their dictionary."""
    value = board.first_id
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InputError(f"board field 'first_id' must be a whole number >= 0, got {value!r}; syntax: {syntax}")
    object.__setattr__(board, "first_id", int(value))
    if value and board.kind not in ("charuco", "aprilgrid"):
        raise InputError(f"board field 'first_id' does not apply to a {board.kind} (it has no marker ids); "
                         f"syntax: {syntax}")
    if board.kind in ("charuco", "aprilgrid"):
        size = _dictionary_size(board.dictionary)
        if board.marker_ids.stop > size:
            raise InputError(f"the {board.kind} board's ids {board.marker_ids.start}..{board.marker_ids.stop - 1} run "
                             f"past the {size} markers of {board.dictionary}; lower first={value}")


def _dictionary_size(name: str) -> int:
    """How many markers an ArUco dictionary holds (its name's count, or OpenCV's own)."""
    match = re.search(r"_(\d+)$", name)
    if match and name.startswith("DICT_") and "X" in name.split("_")[1]:
        return int(match.group(1))
    import cv2

    return int(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name)).bytesList.shape[0])


_KIND_CHECKS = {"charuco": _check_charuco, "aprilgrid": _check_aprilgrid, "circles": _check_circles,
                "circlegrid": _check_circles}
_FIELDS_OF = {"chessboard": (), "charuco": ("marker", "legacy"), "circles": ("diameter",),
              "circlegrid": ("diameter",), "aprilgrid": ("tag_spacing",)}


def _min_count(kind: str) -> int:
    return {"chessboard": 3, "charuco": 3, "circles": 3, "circlegrid": 3, "aprilgrid": 1}[kind]


def _positive(board: Board, name: str, syntax: str) -> None:
    value = getattr(board, name)
    got = number(value)
    if got is None:
        raise InputError(f"board {name} must be a number, got {value!r}; syntax: {syntax}")
    if not np.isfinite(got) or got <= 0:
        raise InputError(f"board {name} must be a positive number, got {value!r}; syntax: {syntax}")
    object.__setattr__(board, name, got)


# -- parsing -----------------------------------------------------------------------------------
_LENGTH = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(mm|m)\s*$")
_SIZE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")
_FILE_SUFFIXES = (".yaml", ".yml", ".json")


def parse_board(spec: str) -> Board:
    """The board a spec names: ``KIND:COLSxROWS:SIZE[:...]`` (module SYNTAX) or the path of a YAML /
    JSON file whose mapping has `kind`, `cols`, `rows`, `spacing`, `unit` and the kind's fields
    (`marker`, `dictionary`, `legacy`, `tag_spacing`, `diameter`). InputError (one line, showing the
    accepted syntax) for anything else."""
    if isinstance(spec, Board):
        return spec
    if not isinstance(spec, str) or not spec.strip():
        raise InputError(f"board spec must be a non-empty text, got {spec!r}; use {SYNTAX_LINE}")
    text = spec.strip()
    if text.lower().endswith(_FILE_SUFFIXES) or Path(text).is_file():
        return _board_from_file(Path(text))
    kind, *fields = [part.strip() for part in text.split(":")]
    kind = kind.lower()
    if kind not in KINDS:
        raise InputError(f"unknown board kind {kind!r} in {text!r}; use {SYNTAX_LINE}")
    syntax = SYNTAX[kind]
    first_id = 0
    if fields and fields[-1].lower().startswith("first="):
        value = fields.pop()[len("first="):].strip()
        if not value.isdigit():
            raise InputError(f"'first=' in {text!r} must be followed by a whole number (the board's first marker "
                             f"id), got {value!r}; syntax: {syntax}")
        first_id = int(value)
    wanted = {"chessboard": (2, 2), "charuco": (4, 5), "circles": (2, 3), "circlegrid": (2, 3), "aprilgrid": (3, 3)}
    low, high = wanted[kind]
    if not low <= len(fields) <= high:
        raise InputError(f"board spec {text!r} has {len(fields)} fields after the kind, a {kind} takes "
                         f"{low}{'' if low == high else f' to {high}'}; syntax: {syntax}")
    size = _SIZE.match(fields[0])
    if size is None:
        raise InputError(f"board size {fields[0]!r} in {text!r} is not COLSxROWS (e.g. 9x6); syntax: {syntax}")
    cols, rows = int(size.group(1)), int(size.group(2))
    spacing, unit = _length(fields[1], text, syntax)
    extra: dict[str, Any] = {}
    if kind == "charuco":
        marker, marker_unit = _length(fields[2], text, syntax)
        extra["marker"] = marker * UNITS[marker_unit] / UNITS[unit]
        extra["dictionary"] = fields[3].upper()
        if len(fields) == 5:
            if fields[4].lower() != "legacy":
                raise InputError(f"the last ChArUco field may only be 'legacy', got {fields[4]!r}; syntax: {syntax}")
            extra["legacy"] = True
    elif kind in ("circles", "circlegrid") and len(fields) == 3:
        diameter, diameter_unit = _length(fields[2], text, syntax)
        extra["diameter"] = diameter * UNITS[diameter_unit] / UNITS[unit]
    elif kind == "aprilgrid":
        try:
            extra["tag_spacing"] = float(fields[2])
        except ValueError:
            raise InputError(f"aprilgrid spacing ratio {fields[2]!r} is not a number (gap / tag size, e.g. "
                             f"0.3); syntax: {syntax}") from None
    return Board(kind, cols, rows, spacing, unit, first_id=first_id, **extra)


def _length(field: str, spec: str, syntax: str) -> tuple[float, str]:
    match = _LENGTH.match(field)
    if match is None:
        raise InputError(f"length {field!r} in {spec!r} must be a positive number with unit mm or m (e.g. "
                         f"25mm, 0.025m); syntax: {syntax}")
    return float(match.group(1)), match.group(2)


def _board_from_file(path: Path) -> Board:
    if not path.is_file():
        raise InputError(f"board file {str(path)!r} does not exist; give a path to a YAML/JSON board file or "
                         f"a spec: {SYNTAX_LINE}")
    try:
        text = path.read_text(encoding="utf-8")
        where = f"board file {str(path)!r}"
        data = load_json(text, where) if path.suffix.lower() == ".json" else load_yaml(text, where)
    except InputError:  # load_yaml's, naming the file and line
        raise
    except (OSError, UnicodeDecodeError, ValueError) as error:
        reason = " ".join(str(error).split())[:120]
        raise InputError(f"board file {str(path)!r} cannot be read as YAML/JSON ({reason})") from None
    if isinstance(data, dict) and isinstance(data.get("board"), dict):
        data = data["board"]
    if not isinstance(data, dict):
        raise InputError(f"board file {str(path)!r} must hold a mapping with kind, cols, rows, spacing, unit")
    known = {f.name for f in dataclasses.fields(Board)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise InputError(f"board file {str(path)!r}: unknown key(s) {', '.join(map(repr, unknown))}; known keys: "
                         f"{', '.join(sorted(known))}")
    missing = [k for k in ("kind", "cols", "rows", "spacing") if k not in data]
    if missing:
        raise InputError(f"board file {str(path)!r} lacks {', '.join(missing)}; e.g. kind: chessboard, cols: 9, "
                         f"rows: 6, spacing: 25, unit: mm")
    fields = dict(data)
    fields["kind"] = str(fields["kind"]).lower()
    fields.setdefault("unit", "mm")
    return Board(**fields)
