"""Kernels: numba-compiled recursions on arrays and floats in SI units, world-frame quantities.

Nothing here validates input: the public functions in :mod:`redysim.dynamics` check sizes and
values at the door and call these. See ``notation.md`` beside this file for the symbols.
"""
