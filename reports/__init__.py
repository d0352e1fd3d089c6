"""Reports: reproductions of the paper's tables and figures, and the comparison report.

Importing the package imports :mod:`harness`, which pins the BLAS libraries to one thread per
process (see there); it must happen before numpy loads OpenBLAS, which ``python -m reports.X``
guarantees.
"""

import harness  # noqa: F401  (pins the BLAS threads)
