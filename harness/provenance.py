"""Where a result came from: package versions, the machine, the git commit, the date."""

from __future__ import annotations

import datetime as _dt
import functools
import os
import platform
import subprocess
import sys
from importlib import metadata
from pathlib import Path

# The source checkout when redysim runs from one (an editable install: harness/ is a folder of
# the repository), else the installed package's folder, where git finds nothing.
REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("numpy", "scipy", "numba")


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return ""


@functools.cache
def cpu_model() -> str:
    """The processor's model name (Linux /proc/cpuinfo, else platform.processor())."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


# OpenBLAS's x86-64 kernels (OPENBLAS_CORETYPE), each with the CPU flags it needs
OPENBLAS_CORETYPES = (
    ("Prescott", ("pni",)),  # SSE3: every x86-64 CPU since 2005
    ("Nehalem", ("sse4_2",)),
    ("Sandybridge", ("avx",)),
    ("Haswell", ("avx2", "fma")),
    ("SkylakeX", ("avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl")),
)


@functools.cache
def cpu_flags() -> frozenset[str]:
    """The processor's feature flags (Linux /proc/cpuinfo; empty elsewhere)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                return frozenset(line.split(":", 1)[1].split())
    except OSError:
        pass
    return frozenset()


def openblas_coretypes() -> list[str]:
    """The OPENBLAS_CORETYPE values this CPU can run, oldest kernel first (for checking that a
    result does not depend on which one OpenBLAS picked)."""
    flags = cpu_flags()
    return [name for name, needs in OPENBLAS_CORETYPES if flags.issuperset(needs)]


PROC_STATUS, PROC_CLEAR_REFS = Path("/proc/self/status"), Path("/proc/self/clear_refs")


def reset_peak_rss() -> bool:
    """Start this process's peak resident set size afresh from its current size (Linux 4.0+:
    ``5`` written to /proc/self/clear_refs resets VmHWM), so that a run measures its own peak
    and not that of the process it was forked from or of the runs before it in a worker.
    False where that is not possible."""
    try:
        PROC_CLEAR_REFS.write_text("5")
        return True
    except OSError:
        return False


def peak_rss_mib() -> float:
    """Peak resident set size of this process [MiB]: Linux's VmHWM (since the last
    :func:`reset_peak_rss`; a new program starts its own), else ``ru_maxrss``, which a child
    inherits from its parent across fork and exec (a long run started by the reproduction
    recorded the reproduction's 1,522 MiB)."""
    try:
        for line in PROC_STATUS.read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


@functools.cache
def code_digest() -> str:
    """SHA-256 of the code a result depends on: every ``.py`` of the core (``redysim/``: the
    kernels, the integrators) and of the engine adapters (``references/``). Part of a run's id
    and of a cached reference solution's key, so that results computed by other code are never
    reused silently."""
    import hashlib

    import redysim
    from redysim import references
    h = hashlib.sha256()
    for root in (Path(redysim.__file__).parent, Path(references.__file__).parent):
        for path in sorted(root.rglob("*.py")):
            h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()


@functools.cache
def git_commit() -> str:
    """The checkout's commit (with ``+dirty`` when the tree has changes), or "" outside git."""
    try:
        out = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short=12", "HEAD"],
                             capture_output=True, text=True, timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(REPO), "status", "--porcelain",
                                "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5).stdout.strip()
        return out + ("+dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return ""


@functools.cache
def _static() -> dict[str, str]:
    return {
        "python": platform.python_version(),
        **{pkg: _version(pkg) for pkg in PACKAGES},
        "redysim": _version("redysim"),
        "machine": f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores",
        "cpu": cpu_model(),
        "git_commit": git_commit(),
    }


def provenance(engine_version: str = "") -> dict[str, str]:
    """One flat dict of provenance columns for a result row."""
    return {**_static(), "engine_version": engine_version,
            "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "executable": sys.executable}
