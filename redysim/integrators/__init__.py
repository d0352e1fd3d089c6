"""The integrator layer: how a state moves in time, given a right-hand side.

- :mod:`redysim.integrators.protocol`: the solver protocol (:class:`OdeSolver`: step, dense
  output, counters, state save and restore), the step controller's constants.
- :mod:`redysim.integrators.explicit`: the Runge-Kutta family (ode45's control), compiled
  stepping, SciPy's solvers behind the protocol.
- :mod:`redysim.integrators.implicit`: the implicit midpoint rule with a chain's tension
  preconditioner.

Imports the model and algorithm layers. See ``docs/design.md``, "Integrators".
"""
