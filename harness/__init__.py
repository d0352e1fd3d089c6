"""The harness around the core: runs (case x engine x integrator), reference solutions, sweeps,
long checkpointed runs, accuracy gates and the ``redysim`` command.

The only place that knows about both the core (:mod:`redysim`) and the reference engines
(:mod:`redysim.references`). Needs the ``harness`` extra (pandas, pyarrow, distributed, tqdm,
psutil, threadpoolctl).

Importing the package limits BLAS to one thread in this process (unless the environment sets a
thread count), with threadpoolctl, which acts at any time, even after numpy loaded OpenBLAS. Runs
here are one process per core: OpenBLAS's own threads on top made SciPy's Cholesky of a 250 x 250
GIM 150x slower on a 2-core machine (0.23 s instead of 1.5 ms per call) and a 100,000-DOF long
run burn 1.5 cores for the work of one.
"""

import os

BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def limit_blas_threads() -> None:
    """One BLAS thread in this process and in the processes it starts, unless the environment
    already sets a thread count."""
    if any(os.environ.get(var) for var in BLAS_THREAD_VARIABLES):
        return
    for var in BLAS_THREAD_VARIABLES:  # child processes inherit these before loading BLAS
        os.environ[var] = "1"
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")


limit_blas_threads()
