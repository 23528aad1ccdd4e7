"""Writing output files so that no run leaves a partial file or overwrites one it should not.

Every file handeye writes (results, reports, simulated data, benchmark figures) goes through
`new_file` (or `write_text` / `write_bytes`):

- the content is written to a temporary file in the target's folder (``.<name>.<random>.part``)
  and flushed to disk (fsync) first, so a run killed at any moment, or a full disk, never leaves
  a truncated target: the target either does not exist or holds a complete earlier file;
- without ``force`` the target is then created **exclusively**: a hard link from the temporary
  file (`os.link` fails when the name exists, atomically), so of two runs writing the same file
  at once one writes and the other is told that the file exists; where the file system has no
  hard links, an exclusive create of the name followed by a rename over it;
- with ``force`` the temporary file is renamed over the target (`os.replace`): the name gets the
  new content, and another name for the same file (a hard link, e.g. to an input) keeps the old
  content;
- any failure removes the temporary file and raises `OSError` naming the target (the CLI turns it
  into a one-line error, exit 2).

`check_writable` creates and removes such a temporary file up front, so a command that would only
write at the end of a long run (``handeye bench --json``) fails before the work, not after it.
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from handeye.base.errors import InputError

#: suffix of the temporary files (a killed run may leave one behind: it is never a result)
PART_SUFFIX = ".part"


def _temporary(path: Path, binary: bool, encoding: str | None, newline: str | None) -> tuple[IO[Any], Path]:
    folder = path.parent if str(path.parent) else Path(".")
    try:
        fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=PART_SUFFIX, dir=folder)
    except OSError as exc:
        raise _naming(exc, path) from None
    os.fchmod(fd, 0o666 & ~_umask())  # as open() would create it (mkstemp makes it private)
    mode = "wb" if binary else "w"
    return os.fdopen(fd, mode, **({} if binary else {"encoding": encoding, "newline": newline})), Path(name)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _naming(exc: OSError, path: Path) -> OSError:
    """`exc` as an OSError whose message names `path` (a disk-full error names no file)."""
    reason = exc.strerror or str(exc)
    return OSError(exc.errno, f"cannot write {str(path)!r}: {reason}")


def _commit(part: Path, path: Path, force: bool, flag: str) -> None:
    if force:
        os.replace(part, path)
        return
    try:
        os.link(part, path)
    except FileExistsError:
        raise InputError(f"{flag} {str(path)!r}: the file exists (another run may have written it meanwhile); "
                         "pass --force to overwrite it, or name another file") from None
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV, errno.EMLINK):
            raise
        # no hard links here: claim the name exclusively, then move the complete file over it
        try:
            os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
        except FileExistsError:
            raise InputError(f"{flag} {str(path)!r}: the file exists (another run may have written it meanwhile); "
                             "pass --force to overwrite it, or name another file") from None
        os.replace(part, path)
        return
    part.unlink()


@contextlib.contextmanager
def new_file(path: str | Path, *, force: bool = False, flag: str = "output", binary: bool = False,
             encoding: str | None = "utf-8", newline: str | None = None) -> Iterator[IO[Any]]:
    """A file object to write `path`'s whole content to; the target appears, complete, when the
    block ends without an exception (module docstring). `force`: replace an existing target
    (else InputError if it exists); `flag`: how the user named the file (``-o``), for messages."""
    path = Path(path)
    fh, part = _temporary(path, binary, None if binary else encoding, newline)
    try:
        with fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        _commit(part, path, force, flag)
    except OSError as exc:
        part.unlink(missing_ok=True)
        raise _naming(exc, path) from None
    except BaseException:
        part.unlink(missing_ok=True)
        raise


def write_text(path: str | Path, text: str, *, force: bool = False, flag: str = "output",
               encoding: str = "utf-8") -> Path:
    """Write `text` to `path` as `new_file` does; return the path."""
    with new_file(path, force=force, flag=flag, encoding=encoding) as fh:
        fh.write(text)
    return Path(path)


def write_bytes(path: str | Path, data: bytes, *, force: bool = False, flag: str = "output") -> Path:
    """Write `data` to `path` as `new_file` does; return the path."""
    with new_file(path, force=force, flag=flag, binary=True) as fh:
        fh.write(data)
    return Path(path)


def check_writable(flag: str, path: str | Path) -> None:
    """InputError unless a file can be created in `path`'s folder (tried with a temporary file,
    removed at once), so that a long run does not fail only when it writes its result."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"{flag} {str(path)!r}: the folder {str(folder)!r} does not exist; create it or name "
                         "another file")
    try:
        fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=PART_SUFFIX, dir=folder)
    except OSError as exc:
        raise InputError(f"{flag} {str(path)!r}: cannot write in the folder {str(folder)!r} "
                         f"({exc.strerror or exc}); name a file in a writable folder") from None
    os.close(fd)
    os.unlink(name)


def check_figure_format(flag: str, path: str | Path) -> None:
    """InputError unless matplotlib can write a figure in the format `path`'s extension names
    (checked before any work, so that a plan is not computed, and its stations written, for a
    figure that then fails)."""
    from matplotlib.figure import Figure

    kinds = sorted(Figure().canvas.get_supported_filetypes())
    ext = Path(path).suffix.lower().lstrip(".")
    if ext not in kinds:
        raise InputError(f"{flag} {str(path)!r}: cannot draw a figure as {ext or '(no extension)'!r}; name a file "
                         f"ending in one of .{', .'.join(kinds)}")
