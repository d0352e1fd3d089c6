"""Reports: reproductions of the paper's tables and figures, and the comparison report.

Importing the package imports :mod:`redysim.harness`, which limits BLAS to one thread per process
(see there).
"""

from redysim import harness  # noqa: F401  (one BLAS thread per process)
