"""Reports: reproductions of the paper's tables and figures, and the comparison report.

Importing the package imports :mod:`redysim.harness`, which limits BLAS to one thread per process
(see there).
"""

if __name__ != "redysim.reports":
    raise ImportError("the folder reports/ is the package redysim.reports: import "
                      f"redysim.reports (python -m redysim.reports.<module>), not {__name__}, "
                      "which would be a second copy of every module in it", name=__name__)

from redysim import harness  # noqa: F401, E402  (one BLAS thread per process)
