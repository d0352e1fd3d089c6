"""What every stepper shares (ours, the implicit midpoint's, SciPy's, an engine's): the solver
protocol, the step controller's constants, the counters, the resumable state, the error they
raise and cubic Hermite interpolation.

A module of its own so that :mod:`redysim.integrators.explicit` and
:mod:`redysim.integrators.implicit` both build on it without importing each other
(``tests/test_layout.py`` refuses import cycles); everything here is also importable from
:mod:`redysim.integrators.explicit`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

# --------------------------------------------------------------------------- controller constants
SAFETY = 0.8            # ode45: new h = h * SAFETY * (rtol / err)^(1 / (q + 1))
DOP853_SAFETY = 0.9    # dop853: Hairer's dop853.f (SAFE) and SciPy's DOP853
MAX_GROWTH = 5.0        # ode45: at most 5x growth after an accepted step
FIRST_REJECT_MIN = 0.1  # ode45: a first rejection shrinks h by no more than 10x
LATER_REJECT = 0.5      # ode45: later rejections of the same step halve h
HMAX_FRACTION = 0.1     # ode45: default hmax = 0.1 * |t_end - t0|
HMIN_EPS = 16.0         # ode45: hmin = 16 eps(t)
FINISH_SLACK = 1.1      # ode45: stretch the last step when 1.1 h reaches t_end
SAMPLE_EPS = 1e-12      # relative slack when matching sample times


class Dynamics(Protocol):
    """What a stepper sees of a system (as SciPy's solvers see ``fun``): its state derivative
    into a buffer, the projection after a step, and, where the derivative is compiled, its
    compiled contract. :class:`redysim.algorithms.system.System` keeps it; :func:`as_dynamics`
    makes a plain ``fun(t, y)`` keep it.

    - ``derivative(t, y, out)``: dy/dt at (t, y) into ``out``; raises (saying why) where it is
      not defined.
    - ``project(y)``: y moved back onto the system's constraints after a step, in place.
    - ``kernel``: ``(data, extras)`` for :mod:`redysim.algorithms._kernels.system`'s compiled
      contract (then the compiled stepping may run), or None.
    """

    kernel: Any

    def derivative(self, t: float, y: np.ndarray, out: np.ndarray) -> None: ...

    def project(self, y: np.ndarray) -> None: ...


class _Function:
    """A plain right-hand side ``fun(t, y) -> dy/dt`` as :class:`Dynamics` (no constraints)."""

    kernel = None

    def __init__(self, fun: Callable):
        self.fun = fun

    def derivative(self, t, y, out) -> None:
        out[:] = self.fun(t, y)

    def project(self, y) -> None:
        return None


def as_dynamics(system) -> Dynamics:
    """``system`` itself when it keeps :class:`Dynamics`, else the plain function ``system(t, y)``
    as one."""
    if hasattr(system, "derivative") and hasattr(system, "kernel"):
        return system
    if not callable(system):
        raise TypeError(f"a stepper takes a function fun(t, y) or a system, not "
                        f"{type(system).__name__}")
    return _Function(system)


def as_function(system) -> Callable:
    """``fun(t, y) -> dy/dt`` (a new array) of a :class:`Dynamics` or a plain function."""
    if not (hasattr(system, "derivative") and hasattr(system, "kernel")):
        return system

    def fun(t, y):
        out = np.empty(np.size(y))
        system.derivative(t, y, out)
        return out

    return fun


class IntegrationError(RuntimeError):
    """The integration cannot go on (step below hmin, a non-finite state)."""


@dataclass
class Counters:
    steps: int = 0
    rejected: int = 0
    nfev: int = 0


@dataclass
class SolverState:
    """Everything needed to resume: time, state, its derivative, the next step, counters."""

    t: float
    y: np.ndarray
    f: np.ndarray
    h: float
    counters: Counters = field(default_factory=Counters)
    sampled_until: float | None = None  # the samples at or before this time were taken

    def resume(self, solver) -> None:
        """Set ``solver``'s time, state, derivative, next step and counters from this state."""
        solver.t, solver.y, solver.f = self.t, self.y.copy(), self.f.copy()
        solver.h_next, solver.counters = self.h, self.counters


def hermite(y0, f0, y1, f1, h, s):
    """y at the fractions ``s`` (m,) of the step [y0, y1] of size h with slopes f0, f1 -> (m, n)."""
    s = s[:, None]
    h00 = (1 + 2 * s) * (1 - s) ** 2
    h10 = s * (1 - s) ** 2
    h01 = s * s * (3 - 2 * s)
    h11 = s * s * (s - 1)
    return h00 * y0 + h10 * h * f0 + h01 * y1 + h11 * h * f1


class OdeSolver(ABC):
    """The protocol every stepper follows (as SciPy's ``OdeSolver``), so that one driver
    (:func:`redysim.integrators.explicit.advance`, :class:`redysim.simulation.Simulator`) runs them
    all.

    Attributes: ``t``, ``y`` (the current time and state), ``t_old`` (the last step's start),
    ``t_end``, ``counters`` (:class:`Counters`: steps, rejected, RHS calls; -1 where a solver
    cannot count). :meth:`step` takes the next sample time ``t_stop``: a fixed step lands on
    it, a compiled solver takes every step up to the first that reaches it, an adaptive one in
    Python ignores it (one accepted step a call). :meth:`dense` interpolates inside the last
    step. :meth:`state` copies what a checkpoint needs to resume (``state=`` of the solver's
    constructor), or raises NotImplementedError where the state cannot be saved (SciPy's, an
    engine's own).
    """

    t: float
    y: np.ndarray
    t_old: float
    t_end: float
    counters: Counters

    @property
    def done(self) -> bool:
        """Whether the solver reached t_end."""
        return self.t >= self.t_end

    @abstractmethod
    def step(self, t_stop: float | None = None) -> None:
        """Advance by one accepted step (or, compiled, up to the first reaching ``t_stop``);
        raises IntegrationError when it cannot."""

    @abstractmethod
    def dense(self, ts) -> np.ndarray:
        """(m, n): y at the times ``ts`` (m,) inside the last step."""

    def state(self) -> SolverState:
        """A copy of the resumable state (to save in a checkpoint)."""
        raise NotImplementedError(f"{type(self).__name__}'s state cannot be saved and resumed")

    def set_deadline(self, clock, deadline: float) -> None:
        """A CPU-time limit (``clock()`` past ``deadline``) for a stepper that does many steps
        in one :meth:`step` of its own control (an engine's adaptive advance; TimeoutError when
        reached); ours return after each step or chunk, where the caller checks its limits."""
        return None
