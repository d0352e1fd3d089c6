"""Errors raised at the door: each names where the bad value came from, the field and the value."""

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


class CaseError(RedysimError, ValueError):
    """A case file or chain description is malformed.

    The message reads ``<source>: <field> = <value>: <what is wrong>`` (no value when it is
    missing) so that a user can find the offending line without reading a traceback.
    """

    def __init__(self, source: str, field: str, value, problem: str):
        self.source = source
        self.field = field
        self.value = value
        self.problem = problem
        shown = f"{field}" if value is None else f"{field} = {_short_repr(value)}"
        super().__init__(f"{source}: {shown}: {problem}")


class StateError(RedysimError, ValueError):
    """A state (q, qd, qdd, tau) handed to a public function has the wrong size or is not finite."""
