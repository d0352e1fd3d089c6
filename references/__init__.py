"""Reference engines: the same model in Pinocchio, MuJoCo, DART, Exudyn and Drake.

One adapter class per engine, registered under its name in :data:`ENGINES` (Pinocchio three
times: ``pinocchio-aba``, ``pinocchio-aba-ryrz`` and ``pinocchio-crba``, one construction with
two U-joint models and two algorithms), every one with the shape of
:class:`redysim.references.base.Engine`: built from a :class:`redysim.Model` (a kinematic tree,
fixed or floating base; a :class:`redysim.Chain` is one, a :class:`redysim.Case` gives its
chain), it answers ``qdd``, ``mass_matrix``, ``bias``, ``energy``, ``position``
(``tip``), ``simulate``, ``version`` and ``limits`` in the core's names, units and coordinates,
a free joint's included. Every adapter builds every joint the core can express (R and P
about/along any axis, U, S, free), from the per-body elementary axes of :func:`joint_axes`.
Importing this package imports no engine: a missing one raises :class:`EngineUnavailable`
(naming the package) only when it is used::

    from redysim import references
    cls = references.get("mujoco")
    if cls.limits(model).ok:                 # decided before building, with the reason
        eng = cls(model)                     # or cls(chain), cls(case): converted at the door
        eng.qdd(q, v, tau); eng.simulate(q0, v0, t_end, h)

Closed loops (:class:`redysim.algorithms.loops.ClosedLoops`: a tree and its cut joints) go to the
loop adapters (:mod:`redysim.references.loops`), which build the tree with the engine's adapter and
close the cuts with each engine's own constraint::

    eng = references.loop_engine("exudyn", loops)   # references.LOOP_ENGINES lists them
    qdd, lam = eng.forward_dynamics_and_forces(q, v, tau)  # as ClosedLoops does
"""

from __future__ import annotations

if __name__ != "redysim.references":
    raise ImportError("the folder references/ is the package redysim.references: import "
                      f"redysim.references, not {__name__}, which would be a second copy of "
                      "every module in it (a second engine registry)", name=__name__)

from .base import (
    Axis,
    Engine,
    EngineLimitExceeded,
    EngineUnavailable,
    JointAxes,
    Limits,
    NativeIntegrator,
    Trajectory,
    as_model,
    joint_axes,
    load_limits,
)
from .dart_engine import DART
from .drake_engine import Drake
from .exudyn_engine import Exudyn
from .loops import LOOP_ENGINES, LoopEngine, LoopStateUnsupported, loop_engine
from .mujoco_engine import MuJoCo
from .pinocchio_engine import PinocchioABA, PinocchioABARyRz, PinocchioCRBA

ENGINES: dict[str, type[Engine]] = {
    cls.name: cls
    for cls in (PinocchioABA, PinocchioABARyRz, PinocchioCRBA, MuJoCo, DART, Exudyn, Drake)
}


def get(name: str) -> type[Engine]:
    """The adapter class registered under ``name`` (see :data:`ENGINES`): build it from a
    :class:`redysim.Model`, the one input (a Chain is one; a Case gives its chain). Raises
    KeyError listing the known names."""
    try:
        return ENGINES[name]
    except KeyError:
        raise KeyError(f"no engine {name!r}; known engines: {', '.join(ENGINES)}") from None


__all__ = ["ENGINES", "LOOP_ENGINES", "Axis", "Engine", "EngineLimitExceeded",
           "EngineUnavailable", "JointAxes", "Limits", "NativeIntegrator", "Trajectory",
           "LoopEngine",
           "LoopStateUnsupported", "as_model", "get", "joint_axes", "load_limits",
           "loop_engine", "DART", "Drake", "Exudyn", "MuJoCo", "PinocchioABA", "PinocchioABARyRz",
           "PinocchioCRBA"]
