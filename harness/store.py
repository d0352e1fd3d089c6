"""Atomic file writes and their readers: a reader sees the old file or the new, never a torn one.

Every writer here writes to a temporary file in the destination's directory (same file system),
flushes and fsyncs it, then renames it over the destination with :func:`os.replace` (atomic on
POSIX and Windows) and fsyncs the directory so the rename itself survives a power cut. A writer
killed mid-write (``kill -9``) leaves at most a stray temporary file, named
``.<name>.<random>.tmp``, which :func:`remove_temp_files` clears::

    from redysim.harness.store import write_parquet_atomic, read_parquet
    write_parquet_atomic(df, "results/runs.parquet")
    df = read_parquet("results/runs.parquet")
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from redysim.errors import RedysimError

if TYPE_CHECKING:  # pandas is imported by the functions that read or write tables
    import pandas as pd

TEMP_PREFIX = "."  # temporary files are hidden, so "*.parquet" globs never see them
TEMP_SUFFIX = ".tmp"
PARQUET_SUFFIX = ".parquet"


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


# A new file's mode, as open() would give it: mkstemp makes its file private (0600), and a
# results folder is often shared (a team, a CI artifact, a web server).
FILE_MODE = 0o666 & ~_umask()


def _fsync_dir(directory: Path) -> None:
    """Make a rename in ``directory`` durable (a no-op where directories cannot be opened)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


class FolderError(RedysimError, OSError):
    """A results folder or file that cannot be written: the message names it, the system's
    reason and what to do. An OSError too, so that code which handles a failed write still
    does."""


def _cannot_write(path: Path, exc: OSError, what: str, flag: str | None) -> FolderError:
    given = f"{flag} " if flag else ""
    if what == "file" and path.is_dir():  # (the rename onto a folder: name it, not the temp file)
        return FolderError(f"{given}{str(path)!r}: is a folder where a file goes; move it away")
    reason = exc.strerror or type(exc).__name__
    # the path the user gave, never the writer's temporary file beside it
    return FolderError(f"{given}{str(path)!r}: the {what} cannot be written ({reason}); make "
                       f"it writable, or give another {flag or 'folder (--out)'}")


def check_kinds(*, files: Iterable[str | os.PathLike] = (),
                folders: Iterable[str | os.PathLike] = (), why: str = "nothing was run") -> None:
    """Refuse, by name and before any work, a path where a file goes but a folder (or other)
    is, or where a folder goes but a file is (:class:`FolderError`); paths not there pass."""
    for f in map(Path, files):
        if f.exists() and not f.is_file():
            raise FolderError(f"{str(f)!r}: is a folder where a file goes; move it away "
                              f"({why})")
    for d in map(Path, folders):
        if d.exists() and not d.is_dir():
            raise FolderError(f"{str(d)!r}: is a file where a folder goes; move it away "
                              f"({why})")


def check_writable(folder: str | os.PathLike, *, what: str = "results folder",
                   flag: str | None = "--out") -> Path:
    """Make ``folder`` (and its parents) if it is not there, then create and remove a file in
    it: called before any run, so that no computation is lost to a folder it cannot be saved
    in. Raises :class:`FolderError` naming the folder (and ``flag``, the option that gave it),
    why, and what to do."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise FolderError(f"{(flag + ' ') if flag else ''}{str(folder)!r}: is a file, not a "
                          f"folder; give a folder for the {what}")
    try:
        probe_write(folder)
    except OSError as exc:
        raise _cannot_write(folder, exc, what, flag) from None
    return folder


def probe_write(folder: Path) -> None:
    """Make ``folder`` (and its parents) if missing, then create and remove a hidden file in
    it: OSError (the system's) where it cannot be written."""
    folder.mkdir(parents=True, exist_ok=True)
    fd, probe = tempfile.mkstemp(dir=folder, prefix=f"{TEMP_PREFIX}probe.{os.getpid()}.",
                                 suffix=TEMP_SUFFIX)
    os.close(fd)
    os.unlink(probe)


def writable(folder: str | os.PathLike) -> bool:
    """Whether :func:`check_writable` would pass (``folder`` made if missing)."""
    try:
        check_writable(folder)
    except FolderError:
        return False
    return True


def sha256_file(path: str | os.PathLike) -> str:
    """The SHA-256 of a file's bytes, in hex."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _write_atomic(path: str | os.PathLike, write: Callable[[IO[bytes]], None], *,
                  if_changed: bool = False) -> Path:
    """Call ``write(fh)`` on a temporary file beside ``path``, then rename it onto ``path``.
    ``if_changed``: leave ``path`` untouched when it already holds those bytes (a finished
    sweep read again rewrites nothing, and so can be read from a folder it cannot write). A
    file that cannot be written raises :class:`FolderError` naming it."""
    path = Path(path)
    if if_changed:
        buf = io.BytesIO()
        write(buf)
        data = buf.getvalue()
        with contextlib.suppress(OSError):
            if path.stat().st_size == len(data) and path.read_bytes() == data:
                return path

        def write(fh, data=data):
            fh.write(data)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        # the writer's pid in the name: remove_temp_files leaves a live writer's file alone
        fd, tmp = tempfile.mkstemp(dir=path.parent,
                                   prefix=f"{TEMP_PREFIX}{path.name}.{os.getpid()}.",
                                   suffix=TEMP_SUFFIX)
    except OSError as exc:
        raise _cannot_write(path, exc, "file", None) from None
    try:
        os.fchmod(fd, FILE_MODE)
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, FolderError):
            raise _cannot_write(path, exc, "file", None) from None
        raise
    _fsync_dir(path.parent)
    return path


def write_parquet_atomic(df: pd.DataFrame, path: str | os.PathLike, *,
                         if_changed: bool = False) -> Path:
    """Write ``df`` (without its index) to the Parquet file ``path`` atomically (``if_changed``:
    see :func:`_write_atomic`)."""
    return _write_atomic(path, lambda fh: df.to_parquet(fh, engine="pyarrow", index=False),
                         if_changed=if_changed)


def write_csv_atomic(df: pd.DataFrame, path: str | os.PathLike) -> Path:
    """Write ``df`` (without its index) to the CSV file ``path`` atomically."""
    return _write_atomic(path, lambda fh: fh.write(df.to_csv(index=False).encode("utf-8")))


def write_text_atomic(text: str, path: str | os.PathLike, *, if_changed: bool = False) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (``if_changed``: see :func:`_write_atomic`)."""
    return _write_atomic(path, lambda fh: fh.write(text.encode("utf-8")), if_changed=if_changed)


def write_json_atomic(obj: Any, path: str | os.PathLike, *, if_changed: bool = False) -> Path:
    """Write ``obj`` as indented JSON to ``path`` atomically."""
    return write_text_atomic(json.dumps(obj, indent=1) + "\n", path, if_changed=if_changed)


def write_npz_atomic(path: str | os.PathLike, **arrays) -> Path:
    """Write ``arrays`` as an uncompressed ``.npz`` file ``path`` atomically."""
    import numpy as np

    return _write_atomic(path, lambda fh: np.savez(fh, **arrays))


def read_parquet(path: str | os.PathLike) -> pd.DataFrame:
    """One Parquet file as a DataFrame."""
    import pandas as pd

    return pd.read_parquet(path, engine="pyarrow")


def parquet_metadata(path: str | os.PathLike):
    """A Parquet file's footer (rows, columns): reads a few kilobytes, and raises if the file is
    truncated or not Parquet."""
    import pyarrow.parquet as pq

    return pq.read_metadata(path)


def read_json(path: str | os.PathLike) -> Any:
    """One JSON file."""
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def parquet_files(directory: str | os.PathLike) -> dict[str, Path]:
    """The finished Parquet files in ``directory`` by stem (``{run_id: path}``); {} if none."""
    directory = Path(directory)
    if not directory.is_dir():
        return {}
    return {p.stem: p for p in sorted(directory.glob(f"*{PARQUET_SUFFIX}"))
            if not p.name.startswith(TEMP_PREFIX)}


def _writer_alive(temp: Path) -> bool:
    """Whether the process that writes ``temp`` (its pid is in the name) is still running."""
    try:
        pid = int(temp.name[:-len(TEMP_SUFFIX)].rsplit(".", 2)[-2])
    except (ValueError, IndexError):
        return False  # not one of ours, or from before names carried the pid
    if pid == os.getpid():
        return False  # this process is not writing it now (it calls from outside a write)
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


def remove_temp_files(directory: str | os.PathLike) -> int:
    """Delete the temporary files that killed writers left in ``directory``; returns how many.
    A file whose writer is still running (another sweep on the same folder) is left alone."""
    directory = Path(directory)
    if not directory.is_dir():
        return 0
    removed = 0
    for p in directory.glob(f"{TEMP_PREFIX}*{TEMP_SUFFIX}"):
        if not _writer_alive(p):
            with contextlib.suppress(FileNotFoundError):
                p.unlink()
                removed += 1
    return removed
