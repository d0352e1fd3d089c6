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


drop_stale_cache()
