"""Kernels: numba-compiled recursions on arrays and floats in SI units, world-frame quantities.

Nothing here validates input: the public functions in :mod:`redysim.algorithms.dynamics` check sizes
and values at the door and call these. See ``notation.md`` beside this file for the symbols.
"""

from __future__ import annotations

import hashlib
import os
from itertools import chain
from pathlib import Path

HERE = Path(__file__).parent
STAMP = "kernel-sources.sha256"


def sources_digest() -> str:
    """SHA-256 of every kernel source and of ``redysim/_jit.py`` (the compile options)."""
    h = hashlib.sha256()
    for p in sorted(HERE.glob("*.py")) + [HERE.parent.parent / "_jit.py"]:
        h.update(p.name.encode() + b"\0" + p.read_bytes())
    return h.hexdigest()


def drop_stale_cache(cache: Path = HERE / "__pycache__") -> bool:
    """Delete numba's on-disk cache beside the kernels if any kernel source changed since it was
    written; True if it did.

    numba checks only a kernel's own file when it loads the kernel's machine code from disk, so an
    edit to a callee in another file (``jcalc`` in joints.py, inlined into kinematics.py) would
    keep the old code running, silently. Run once at import; a read-only install skips it (numba
    then caches elsewhere, and a reinstall changes every file anyway).
    """
    digest = sources_digest()
    stamp = cache / STAMP
    try:
        if stamp.read_text() == digest:
            return False
    except OSError:
        pass
    try:
        cache.mkdir(exist_ok=True)
        for f in chain(cache.glob("*.nbi"), cache.glob("*.nbc")):
            f.unlink(missing_ok=True)
        tmp = cache / f".{STAMP}.{os.getpid()}.tmp"
        tmp.write_text(digest)
        os.replace(tmp, stamp)
    except OSError:
        return False
    return True


def compiled_cache_dir() -> Path | None:
    """Where numba keeps these kernels' machine code (beside them, or where NUMBA_CACHE_DIR or a
    read-only install sends it: numba's own choice, asked of numba); None if numba cannot say."""
    try:
        from numba.core.caching import FunctionCache

        return Path(FunctionCache(sources_digest)._cache_path)
    except Exception:  # (numba internals of another version: no answer, no note)
        return None


# shown once per process on stderr when the kernels' cache is empty: numba then compiles each
# kernel on its first call, which takes a minute or two of a first run (docs/guide.md)
COLD_NOTE = ("redysim: compiling the numba kernels for this machine on first use (about 1.5 "
             "min of CPU for a first run; cached in {where}, so later processes start at once)")


def announce_cold_cache(stream=None) -> bool:
    """Say on ``stream`` (stderr) that the first calls will compile, when the kernels' cache
    holds no compiled kernel; True if it said so."""
    import sys

    where = compiled_cache_dir()
    if where is None or os.environ.get("NUMBA_DISABLE_JIT", "0") not in ("", "0"):
        return False
    try:
        if any(where.glob("*.nbi")):
            return False
    except OSError:
        pass
    print(COLD_NOTE.format(where=where), file=stream or sys.stderr, flush=True)
    return True


drop_stale_cache()
announce_cold_cache()
