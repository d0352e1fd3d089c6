"""The harness around the core: runs (case x engine x integrator), reference solutions, sweeps.

The only place that knows about both the core (``redysim``) and the reference engines
(``references``). Needs the ``harness`` extra (pandas, pyarrow, distributed, tqdm, psutil).
"""
