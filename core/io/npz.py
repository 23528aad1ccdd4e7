"""Reading NPZ archives (``numpy.savez``) without trusting them.

`numpy.load` returns an NPZ member that is not a ``.npy`` array as raw bytes, and allocates the
array a member's header claims before reading its data: a header of a few bytes can claim
terabytes (a MemoryError, or minutes of swapping). And a member may legitimately inflate far
beyond the archive: ``np.savez_compressed`` of a zero array of 4.8 GB is a 4.7 MB file whose
headers are all consistent (a decompression bomb).

`load_npz` therefore checks, with one-line InputErrors naming the file and the member:

1. from the archive's central directory alone, before any member is opened or inflated
   (`_check_sizes`): each member's compression method, its declared uncompressed size, its
   compression ratio, and the archive's declared total, against the limits below;
2. each member's ``.npy`` header (`numpy.lib.format.read_magic`, `read_array_header_1_0` /
   `read_array_header_2_0`): members that are not ``.npy``, Python objects (pickles), and shapes
   whose size exceeds the bytes the member declares;

and only then reads the arrays, by `numpy.load` without pickles.

Limits (the largest legitimate input is 10^6 pose pairs, the most ``handeye simulate`` writes:
two (10^6, 4, 4) float64 stacks of 128 MB each, 256 MB):

- `MAX_MEMBER_BYTES` = 256 MB a member: twice one such stack;
- `MAX_ARCHIVE_BYTES` = 512 MB all members together: twice such a file (room for stamps, names,
  truth); beyond that handeye could not compute with the data anyway (every solver copies it);
- `MAX_RATIO` = 500 for members of more than `RATIO_FLOOR` = 10 MB: deflate cannot exceed about
  1030:1, reached by a run of one byte value (an array of zeros: a bomb); the most compressible
  real pose data, one pose repeated (a robot standing still, recorded for a long time), inflates
  about 290:1, and random poses 1.4:1. Small members are exempt: they cost nothing, and small
  arrays of zeros (stamps, a mask) are legitimate.
- methods: stored and deflated only, the two numpy writes.

Why the declared sizes bound what is read (CPython's zipfile, Lib/zipfile.py `ZipExtFile._read1`):
the output of a member is cut at its declared size (``data[:self._left]``) and a CRC mismatch
raises BadZipFile, so a member never yields more than the directory declares. Decompression
itself is bounded per call only for deflate (``decompress(data, max_length)`` with max_length =
the size asked of read(), at least 4 kB); bzip2 and lzma members are decompressed without a
max_length (178 bytes of bzip2 hold 200 MB of zeros, all inflated by one read before the cut),
hence refused. Nothing here calls read() without a size (that would pass max_length = 2 GiB):
numpy reads array data in chunks of at most 256 kB (``numpy.lib.format.BUFFER_SIZE``), and the
header checks read the magic, the header length and the header (numpy caps it at 10 kB).
"""

from __future__ import annotations

import math
import zipfile
import zlib
from pathlib import Path

import numpy as np

from handeye.base.errors import InputError

#: exceptions of zipfile / numpy for an archive that cannot be read (damaged, truncated, encrypted,
#: compressed with an unsupported method, or a .npy header that does not parse)
UNREADABLE = (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, NotImplementedError, RuntimeError)
#: largest declared uncompressed size of one member, and of all members (module docstring)
MAX_MEMBER_BYTES = 256 * 10**6
MAX_ARCHIVE_BYTES = 512 * 10**6
#: largest compression ratio (uncompressed / compressed) of a member of more than RATIO_FLOOR bytes
MAX_RATIO = 500
RATIO_FLOOR = 10 * 10**6
#: compression methods read: those numpy.savez / savez_compressed write
METHODS = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflated"}
_METHOD_NAMES = {zipfile.ZIP_BZIP2: "bzip2", zipfile.ZIP_LZMA: "lzma"}


def load_npz(path: str | Path, where: str) -> dict[str, np.ndarray]:
    """Every array of the NPZ file `path`, by name (``"A"`` for member ``A.npy``), after the
    checks of the module docstring. `where` names the file in messages (e.g. its quoted path).
    Raises InputError for anything but an archive of plain .npy arrays that hold their data
    within the size limits."""
    try:
        with zipfile.ZipFile(path) as archive:
            infos = archive.infolist()
            _check_sizes(infos, where)  # from the central directory: nothing is inflated before this
            for info in infos:
                _check_member(archive, info, where)
        # zipfile cannot be made to yield more than a member's declared size (ZipExtFile cuts its
        # output there; deflate inflates at most one read's worth, numpy reads <= 256 kB at a time;
        # bzip2 / lzma, which inflate a whole read at once, were refused): module docstring
        with np.load(path, allow_pickle=False) as npz:
            return {key: npz[key] for key in npz.files}
    except InputError:
        raise
    except UNREADABLE as exc:
        raise InputError(f"{where}: not a readable NPZ file ({' '.join(str(exc).split())})") from None


def _check_sizes(infos: list[zipfile.ZipInfo], where: str) -> None:
    """InputError for a member of another compression method than numpy's, or whose declared
    uncompressed size or compression ratio exceeds the limits, or an archive whose members
    together exceed `MAX_ARCHIVE_BYTES`. Reads nothing but the directory entries."""
    for info in infos:
        name = _key(info)
        if info.compress_type not in METHODS:
            method = _METHOD_NAMES.get(info.compress_type, f"method {info.compress_type}")
            raise InputError(f"{where}: NPZ member {name!r} is compressed with {method}, which is not read; "
                             "save the arrays with numpy.savez or numpy.savez_compressed")
        if info.file_size > MAX_MEMBER_BYTES:
            raise InputError(f"{where}: NPZ member {name!r} declares {_bytes(info.file_size)} uncompressed, more "
                             f"than the {_bytes(MAX_MEMBER_BYTES)} a member may hold (twice a stack of 10^6 poses); "
                             "split the data or check the file")
        ratio = info.file_size / max(info.compress_size, 1)
        if info.file_size > RATIO_FLOOR and ratio > MAX_RATIO:
            raise InputError(f"{where}: NPZ member {name!r} inflates {ratio:.0f} times ({_bytes(info.compress_size)} "
                             f"to {_bytes(info.file_size)}), more than pose data can (at most {MAX_RATIO}); "
                             "a decompression bomb or an array of one repeated value")
    total = sum(info.file_size for info in infos)
    if total > MAX_ARCHIVE_BYTES:
        raise InputError(f"{where}: the NPZ members declare {_bytes(total)} uncompressed together, more than the "
                         f"{_bytes(MAX_ARCHIVE_BYTES)} a file may hold (twice 10^6 pose pairs); split the data")


def _check_member(archive: zipfile.ZipFile, info: zipfile.ZipInfo, where: str) -> None:
    """InputError unless member `info` is a .npy array of numbers whose header's shape and dtype
    fit in the member's size (uncompressed, as the archive's directory states it)."""
    name = info.filename
    if not name.endswith(".npy"):
        raise InputError(f"{where}: NPZ member {name!r} is not a .npy array; an NPZ file holds only .npy arrays "
                         "(as numpy.savez writes them)")
    key = _key(info)
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


def _key(info: zipfile.ZipInfo) -> str:
    """The array name of a member (``A`` for ``A.npy``), or the member's name when it is no .npy."""
    return info.filename.removesuffix(".npy")


def _bytes(n: int) -> str:
    for unit, size in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n} bytes"
