"""Benchmarks record the versions and the machine with every result."""

from __future__ import annotations

import os
import platform

import numba
import numpy as np
import pytest

import redysim


def machine() -> dict:
    cpu = platform.processor() or "unknown"
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next(line.split(":", 1)[1].strip() for line in fh
                       if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(),
            "numpy": np.__version__, "numba": numba.__version__, "redysim": redysim.__version__}


@pytest.fixture
def record(benchmark):
    """benchmark.extra_info with the machine, plus a helper to add ns/DOF after the run."""
    benchmark.extra_info.update(machine())
    return benchmark.extra_info
