"""The model layer: what a mechanism is, before anything is computed on it.

- :mod:`redysim.model.parts`: joint types (R, P, U, S, ...), :class:`Joint`, :class:`Link`, the
  checks of their values.
- :mod:`redysim.model.tree`: :class:`Model` (a tree of bodies: the one model type),
  :class:`Chain` (a Model laid out as a serial chain), :class:`CutJoint` (a closed mechanism is
  its tree with cut joints), :class:`Body`, :class:`TreeJoint`.
- :mod:`redysim.model.shapes`: initial shapes of a chain (the catenary).

Imports nothing above it (``tests/test_layout.py``); users import the public names from
``redysim``. See ``docs/design.md``, "Layers".
"""
