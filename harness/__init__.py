"""The harness around the core: runs (case x engine x integrator), reference solutions, sweeps.

The only place that knows about both the core (``redysim``) and the reference engines
(``references``). Needs the ``harness`` extra (pandas, pyarrow, distributed, tqdm, psutil).

Importing the package pins the BLAS libraries to one thread per process (unless the environment
already says otherwise); it takes effect when it happens before numpy loads OpenBLAS, as with
``python -m harness.X`` and ``python -m reports.X``. Runs here are one process per core, and on
this 2-core machine OpenBLAS's own threads made SciPy's Cholesky of a 250 x 250 GIM 150x slower
(0.23 s instead of 1.5 ms per call) and a 100,000-DOF long run burn 1.5 cores for the work of one.
"""

import os

BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
for _var in BLAS_THREAD_VARIABLES:
    os.environ.setdefault(_var, "1")
