"""Errors raised at the door: each names where the bad value came from, the field and the value.

::

    RedysimError                  every error redysim raises on purpose +-- FieldError
    a bad field of a file or a call (names source, field, value) |   +-- CaseError             a
    case file or chain description (redysim.io.cases, redysim.model.tree) |   +-- SettingsError
    a run's settings: integrator, tolerances, step, horizon, sampling |   +-- SweepError
    a sweep file (redysim.harness.sweep) |   +-- GatesError            the accuracy gates file
    (redysim.harness.gates) |   +-- ModelFileError        a URDF or MJCF file (redysim.io.importers)
    |   +-- ModelTypeError (also a TypeError) not a redysim.Model where one is taken
    +-- StateError                a state (q, v, qdd, tau) handed to a dynamics function
"""

from __future__ import annotations

import reprlib


class RedysimError(Exception):
    """Base class of every error redysim raises on purpose."""


def plain(value):
    """``value`` with numpy scalars and arrays turned into Python numbers and lists (inside
    tuples, lists and dicts too), so that a message shows ``0.5``, not ``np.float64(0.5)``."""
    import numpy as np

    if isinstance(value, np.ndarray | np.generic):
        return value.tolist()
    if isinstance(value, list | tuple):
        items = [plain(v) for v in value]
        return items if isinstance(value, list) else tuple(items)
    if isinstance(value, dict):
        return {plain(k): plain(v) for k, v in value.items()}
    return value


def _short_repr(value, limit: int = 200) -> str:
    """repr(value) with numpy numbers as plain ones (:func:`plain`), abbreviated by reprlib when
    longer than ``limit`` characters (a whole table given where a number was expected would
    otherwise flood the message)."""
    value = plain(value)
    text = repr(value)
    if len(text) <= limit:
        return text
    r = reprlib.Repr()
    r.maxlist = r.maxtuple = r.maxdict = 4
    r.maxstring = r.maxother = 60
    r.maxlevel = 2
    return r.repr(value)


class FieldError(RedysimError, ValueError):
    """A bad field: the message reads ``<source>: <field> = <value>: <what is wrong>`` (no value
    when the field is missing), so that a user finds the offending line without a traceback.

    Attributes: ``source`` (a file's path, or what was called), ``field`` (its dotted name in the
    file, or the argument's name), ``value`` and ``problem``.
    """

    def __init__(self, source: str, field: str, value, problem: str):
        self.source = source
        self.field = field
        self.value = value
        self.problem = problem
        shown = f"{field}" if value is None else f"{field} = {_short_repr(value)}"
        super().__init__(f"{source}: {shown}: {problem}")


class CaseError(FieldError):
    """A case file or chain description is malformed."""


class SettingsError(FieldError):
    """A run's settings (integrator, rtol, atol, h, t_end, sample interval) are out of range."""


class ModelFileError(FieldError):
    """A URDF or MJCF file (or an option of its loader) the importer cannot take:
    ``<file>: <element>.<attribute> = <value>: <what is wrong>``, the element named as the file
    names it (``joint 'knee'``, ``link 'base'``, ``body 'torso'``)."""


class StateError(RedysimError, ValueError):
    """A state (q, v, qdd, tau) handed to a public function has the wrong size or is not finite,
    or the dynamics of a finite state are singular or overflow (the message says which)."""


class ModelTypeError(CaseError, TypeError):
    """Something that is not a :class:`redysim.Model` handed where a model is taken: a
    TypeError (the wrong kind of argument), and a :class:`CaseError` naming the call and the
    type given, as every refusal of a model."""
