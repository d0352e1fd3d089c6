"""The algorithm layer: what is computed on a model at one state.

- :mod:`redysim.algorithms.dynamics`: the public functions (forward and inverse dynamics, the
  GIM, its U D U^T, energy, tip and frame motion), checked at the door, then the kernels.
- :mod:`redysim.algorithms._kernels`: the numba kernels, one file per algorithm, the paper's
  names (``notation.md``); ``bundles.py`` declares the data layout once.
- :mod:`redysim.algorithms.workspace`: per-model scratch (Pinocchio's ``Data``).
- :mod:`redysim.algorithms.rbda`: the same recursions in plain numpy, the readable reference.
- :mod:`redysim.algorithms.loops`: forward dynamics and projection with cut joints closed.
- :mod:`redysim.algorithms.loads`: a tip force as joint torques and potential.
- :mod:`redysim.algorithms.coarse`: coarse-graining a chain, and the state maps.
- :mod:`redysim.algorithms.precision`: the kernels in rounded / IEEE reduced arithmetic.
- :mod:`redysim.algorithms.linkages`: the closed forms the loops are checked against.
- :mod:`redysim.algorithms.methods`: the algorithm names.

Imports the model layer only. See ``docs/design.md``, "Layers".
"""
