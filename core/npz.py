"""Reading NPZ archives (``numpy.savez``) without trusting them.

`numpy.load` returns an NPZ member that is not a ``.npy`` array as raw bytes, and allocates the
array a member's header claims before reading its data: a header of a few bytes can claim
terabytes (a MemoryError, or minutes of swapping). `load_npz` reads every member's header first
(`numpy.lib.format.read_magic`, `read_array_header_1_0` / `read_array_header_2_0`) and refuses,
with one-line InputErrors naming the file and the member: members that are not ``.npy``, Python
objects (pickles), and shapes whose size exceeds the bytes the member holds. Only then are the
arrays read, by `numpy.load` without pickles.
"""

from __future__ import annotations

import math
import zipfile
import zlib
from pathlib import Path

import numpy as np

from .errors import InputError

#: exceptions of zipfile / numpy for an archive that cannot be read (damaged, truncated, encrypted,
#: compressed with an unsupported method, or a .npy header that does not parse)
UNREADABLE = (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, NotImplementedError, RuntimeError)


def load_npz(path: str | Path, where: str) -> dict[str, np.ndarray]:
    """Every array of the NPZ file `path`, by name (``"A"`` for member ``A.npy``), after the
    checks of the module docstring. `where` names the file in messages (e.g. its quoted path).
    Raises InputError for anything but an archive of plain .npy arrays that hold their data."""
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                _check_member(archive, info, where)
        with np.load(path, allow_pickle=False) as npz:
            return {key: npz[key] for key in npz.files}
    except InputError:
        raise
    except UNREADABLE as exc:
        raise InputError(f"{where}: not a readable NPZ file ({' '.join(str(exc).split())})") from None


def _check_member(archive: zipfile.ZipFile, info: zipfile.ZipInfo, where: str) -> None:
    """InputError unless member `info` is a .npy array of numbers whose header's shape and dtype
    fit in the member's size (uncompressed, as the archive's directory states it)."""
    name = info.filename
    if not name.endswith(".npy"):
        raise InputError(f"{where}: NPZ member {name!r} is not a .npy array; an NPZ file holds only .npy arrays "
                         "(as numpy.savez writes them)")
    key = name[:-len(".npy")]
    with archive.open(info) as fp:
        version = np.lib.format.read_magic(fp)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(fp)
        elif version in ((2, 0), (3, 0)):  # 3.0: the 2.0 layout with a UTF-8 header
            shape, _, dtype = np.lib.format.read_array_header_2_0(fp)
        else:
            raise InputError(f"{where}: NPZ member {key!r} is a .npy array of format version {version}, which is not read")
        header = fp.tell()
    if dtype.hasobject:
        raise InputError(f"{where}: NPZ member {key!r} holds Python objects (a pickle), which are not read; "
                         "save arrays of numbers or strings")
    needed = math.prod(shape) * dtype.itemsize
    held = info.file_size - header
    if needed > held:
        raise InputError(f"{where}: NPZ member {key!r} claims shape {tuple(shape)} of {dtype} ({_bytes(needed)}) but "
                         f"holds {_bytes(held)}; the file is damaged or was not written by numpy.savez")


def _bytes(n: int) -> str:
    for unit, size in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n} bytes"
