"""The harness around the core: runs (case x engine x integrator), reference solutions, sweeps,
long checkpointed runs, accuracy gates and the ``redysim`` command.

The only place that knows about both the core (:mod:`redysim`) and the reference engines
(:mod:`redysim.references`). Its runs, sweeps and reports need the ``harness`` extra (pandas,
pyarrow, distributed, tqdm, psutil, threadpoolctl); the ``redysim`` command itself (this package,
:mod:`redysim.harness.cli`) imports without it, and a command that needs an extra says which.

This folder of the repository installs as ``redysim.harness`` and imports under that name only:
as a top-level ``harness`` (Python started in the checkout's root puts the folder on sys.path)
every module in it would load a second time, beside the first, with classes of its own.

Importing the package limits BLAS to one thread in this process (unless the environment sets a
thread count), with threadpoolctl, which acts at any time, even after numpy loaded OpenBLAS. Runs
here are one process per core, and OpenBLAS's own threads on top of them made a small Cholesky
many times slower and a long run burn more cores for the work of one
(docs/notes/2026-11-costs-in-the-code.md). Without threadpoolctl (an install without the
``harness`` extra, which runs no process pool) only the environment is set: the processes this
one starts take one thread; this one keeps the BLAS threads numpy started with. Likewise a pool
worker runs redysim's batches on one thread (:func:`worker_threads`).
"""

import os

if __name__ != "redysim.harness":
    raise ImportError("the folder harness/ is the package redysim.harness: import "
                      f"redysim.harness (python -m redysim.harness.<module>), not {__name__}, "
                      "which would be a second copy of every module in it", name=__name__)

BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def limit_blas_threads() -> None:
    """One BLAS thread in this process and in the processes it starts, unless the environment
    already sets a thread count; in the processes it starts only, without threadpoolctl."""
    if any(os.environ.get(var) for var in BLAS_THREAD_VARIABLES):
        return
    for var in BLAS_THREAD_VARIABLES:  # child processes inherit these before loading BLAS
        os.environ[var] = "1"
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # no harness extra: no process pool either
        return
    threadpool_limits(limits=1, user_api="blas")


limit_blas_threads()

# redysim's batches (forward_dynamics on (B, n) arrays, simulate_batch) use every core unless this
# variable says otherwise (redysim.algorithms.threads.default_threads). The harness's process pools
# run one process per core: their workers take one thread each (worker_threads).
REDYSIM_THREADS = "REDYSIM_THREADS"


def worker_threads() -> None:
    """In a pool worker process (the sweeps' and refinement's pools, the local Dask cluster's
    workers): one thread for redysim's batches, unless the environment already sets
    REDYSIM_THREADS (then that). BLAS is one thread already (:func:`limit_blas_threads`, run on
    import, and the environment a worker inherits); no kernel uses numba's own threads."""
    if not os.environ.get(REDYSIM_THREADS):
        os.environ[REDYSIM_THREADS] = "1"
