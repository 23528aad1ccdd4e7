"""The detections of a whole image set, as fast as the best-corner rule allows: stored ones from
the cache (`handeye.vision.detection_cache`), the others over the cores
(`handeye.vision.detection_pool`), and for chessboards a plan of which detector flag sets to run.

Why a plan: every chessboard image ran all four ``findChessboardCornersSB`` flag sets
(`handeye.vision.detect.SB_FLAG_SETS`) so that `handeye.vision.best_corners.choose` could keep the
corners that fit best; the two with ``CALIB_CB_ACCURACY`` cost ~4x the others (30 images of 1.3 MP:
~1.5 s an image in all). But a set's images are alike: the flag sets whose corners the rule keeps on
a few of them are the ones it keeps on all. So (`flag_set_plan`):

1. `PROBE_IMAGES` images spread over the set run every flag set;
2. `choose` judges them (with the given intrinsics, else intrinsics calibrated from them), and the
   plan is the flag sets it kept there, plus the one whose corners ``cornerSubPix`` starts from
   (so that candidate is the same as in a full run);
3. the other images run the planned flag sets only; where none of them finds the board, every
   other one runs (`handeye.vision.detect.detect`'s ``flag_sets``), as in a full run;
4. an image whose corners then fit the camera far worse than the others' (`doubtful`) runs every
   flag set: the planned ones may agree on a wrong numbering that the others would outvote.

`choose` then judges the whole set as before: the rule is unchanged, it only no longer sees the
candidates that lost on every probe image. Measured on 30 rendered 1.3 MP chessboard images (blur,
noise, distortion; bench/images_speed.py): the corners kept, K and dist bit-identical to the full
run, about half the detection work (SB with ACCURACY, kept on 25 of the 30 images, is the one flag
set the plan runs). Boards of the other kinds run everything (their detectors cost 20-60 ms an
image), as does a chessboard set of fewer than `PLAN_MIN_IMAGES` images, or one whose probe cannot
be judged (fewer than three boards found and no intrinsics).

Before any of this, a chessboard set's probe images are surveyed for the board they show
(`handeye.vision.board_survey`, ~0.5 s): a wrong board size is named at once instead of after the
long search (skipped when the probe images' detections are in the cache).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from handeye.vision.boards import Board
from handeye.vision.detection_cache import DetectionCache, file_digest
from handeye.vision.image_detection import Outcome
from handeye.vision.observations import Camera

#: images run with every flag set to make the plan
PROBE_IMAGES = 4
#: an image fitting the set's camera this many times worse than the median one runs every flag set
DOUBT_FACTOR = 2.0
#: fewest chessboard images for a plan (below, the probe would be most of the set)
PLAN_MIN_IMAGES = 8
_REFINED = "cornerSubPix on "


def detect_set(files: Sequence[Path], board: Board, camera: Camera | None = None, *, workers: int | None = None,
               cache: bool | str | Path | None = None, progress: bool = True) -> list[Outcome]:
    """One `Outcome` per file, in order (module docstring). `camera`: the intrinsics, if given (the
    plan's probe is judged with them); `workers`: detection threads (default: the cores);
    `cache`: None / True the environment's cache, False none, a folder that one; `progress`: a
    progress bar on a terminal."""
    from handeye.framework.progress import progress_bar
    from handeye.vision.board_survey import check_chessboard_size

    everything = range(len(files))
    with progress_bar(len(files), "detecting the board", "image", progress) as bar:
        run = _Runner(files, board, DetectionCache.resolve(cache), workers, bar.update)
        probes = probe_indices(len(files))
        if board.kind == "chessboard" and not run.cached(probes):  # a wrong board size named before the long search
            check_chessboard_size([files[k] for k in probes], board, workers)
        if board.kind != "chessboard" or len(files) < PLAN_MIN_IMAGES:
            found = run(everything, None)
        else:
            found = run(probe_indices(len(files)), None)
            plan = flag_set_plan([found[k] for k in sorted(found)], camera)
            rest = run([k for k in everything if k not in found], plan)
            if plan is not None:
                rest.update(run(doubtful(rest, camera), None))
            found.update(rest)
    return [found[k] for k in everything]


def probe_indices(count: int) -> list[int]:
    """`PROBE_IMAGES` indices spread evenly over `count` images (all of them when fewer)."""
    return sorted({int(round(v)) for v in np.linspace(0, count - 1, min(PROBE_IMAGES, count))})


def flag_set_plan(probe: Sequence[Outcome], camera: Camera | None) -> tuple[str, ...] | None:
    """The chessboard flag sets to run on the rest of a set, judged on its probe images' outcomes
    (module docstring); None: all of them."""
    from handeye.vision.best_corners import choose
    from handeye.vision.detect import SB_FLAG_SETS

    found = [o for o in probe if o.detection is not None]
    if not found:
        return None
    size = Counter(o.size for o in found).most_common(1)[0][0]
    choice = choose([o.detection for o in found], camera, size)
    if camera is None and choice.calibration is None:
        return None
    names = {d.method.removeprefix(_REFINED) for d in choice.detections}
    names |= {o.detection.method.removeprefix(_REFINED) for o in found}  # cornerSubPix's start
    plan = tuple(name for name, _ in SB_FLAG_SETS if name in names)
    return None if not plan or len(plan) == len(SB_FLAG_SETS) else plan


def doubtful(outcomes: dict[int, Outcome], camera: Camera | None) -> list[int]:
    """The images (keys of `outcomes`) whose first candidate fits the camera (given, else calibrated
    from those candidates) `DOUBT_FACTOR` x worse than the median image: they run every flag set,
    so that corners the planned flag sets agree on wrongly (a board numbered a row off) are outvoted
    by the others, as in a full run, instead of making an outlier the image set drops."""
    from handeye.base.errors import InputError
    from handeye.vision.best_corners import fit_rms
    from handeye.vision.intrinsics import calibrate_camera

    found = {k: o for k, o in sorted(outcomes.items()) if o.detection is not None}
    if len(found) < 3:
        return []
    if camera is None:
        size = Counter(o.size for o in found.values()).most_common(1)[0][0]
        try:
            camera = calibrate_camera([o.detection for o in found.values()], size).camera
        except InputError:
            return []
    errors = {k: fit_rms(o.detection, camera) for k, o in found.items()}
    limit = DOUBT_FACTOR * float(np.median(list(errors.values())))
    return [k for k, e in errors.items() if e > limit]


class _Runner:
    """Outcomes of some of the files with one flag-set plan: from the cache, else detected (then
    stored)."""

    def __init__(self, files: Sequence[Path], board: Board, store: DetectionCache | None, workers: int | None,
                 done: Callable[[], object]) -> None:
        self.files, self.board, self.store, self.workers, self.done = files, board, store, workers, done
        self.digests = [file_digest(f) if store else None for f in files]

    def __call__(self, indices: Sequence[int], plan: tuple[str, ...] | None) -> dict[int, Outcome]:
        from handeye.vision import detection_pool

        keys = {k: self._key(k, plan) for k in indices}
        out: dict[int, Outcome] = {}
        for k, key in keys.items():
            hit = None if key is None else self.store.get(key, self.board)
            if hit is not None:
                out[k] = hit
                self.done()
        missing = [k for k in indices if k not in out]
        items = [(str(self.files[k]), self.board, plan) for k in missing]
        for k, outcome in zip(missing, detection_pool.run(items, self.workers, done=self.done)):
            out[k] = outcome
            if keys[k] is not None:
                self.store.put(keys[k], outcome)
        return out

    def cached(self, indices: Sequence[int]) -> bool:
        """Whether every one of `indices` has its outcome (with every flag set) in the cache: the
        images were detected before, and their board size surveyed then."""
        keys = [self._key(k, None) for k in indices]
        return bool(keys) and all(key is not None and self.store.get(key, self.board) is not None for key in keys)

    def _key(self, k: int, plan: tuple[str, ...] | None) -> str | None:
        if self.store is None or self.digests[k] is None:
            return None
        return self.store.key(self.digests[k], self.board, ("flag sets", plan))
