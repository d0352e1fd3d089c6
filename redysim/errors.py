"""Errors raised at the door: each names where the bad value came from, the field and the value.

::

    RedysimError                  every error redysim raises on purpose
    +-- FieldError                a bad field of a file or a call (names source, field, value)
    |   +-- CaseError             a case file or chain description (redysim.cases, redysim.chain)
    |   +-- SettingsError         a run's settings: integrator, tolerances, step, horizon, sampling
    |   +-- SweepError            a sweep file (redysim.harness.sweep)
    |   +-- GatesError            the accuracy gates file (redysim.harness.gates)
    +-- StateError                a state (q, qd, qdd, tau) handed to a dynamics function
"""

from __future__ import annotations

import reprlib


class RedysimError(Exception):
    """Base class of every error redysim raises on purpose."""


def _short_repr(value, limit: int = 200) -> str:
    """repr(value), abbreviated by reprlib when longer than ``limit`` characters (a whole table
    given where a number was expected would otherwise flood the message)."""
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


class StateError(RedysimError, ValueError):
    """A state (q, qd, qdd, tau) handed to a public function has the wrong size or is not finite,
    or the dynamics of a finite state are singular or overflow (the message says which)."""
