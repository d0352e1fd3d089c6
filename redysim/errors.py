"""Errors raised at the door: each names where the bad value came from, the field and the value."""

from __future__ import annotations


class RedysimError(Exception):
    """Base class of every error redysim raises on purpose."""


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
        shown = f"{field}" if value is None else f"{field} = {value!r}"
        super().__init__(f"{source}: {shown}: {problem}")


class StateError(RedysimError, ValueError):
    """A state (q, qd, qdd, tau) handed to a public function has the wrong size or is not finite."""
