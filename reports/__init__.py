"""Reports: reproductions of the paper's tables and figures, and the comparison report.

Importing the package pins the BLAS libraries to one thread per process (unless the environment
already says otherwise); it must happen before numpy loads OpenBLAS, which ``python -m reports.X``
guarantees. The sweeps and timings here run one process per core, and on this shared 2-core
machine OpenBLAS's own threads made SciPy's Cholesky of a 250 x 250 GIM 150x slower (0.23 s
instead of 1.5 ms per call).
"""

import os

BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
for _var in BLAS_THREAD_VARIABLES:
    os.environ.setdefault(_var, "1")
