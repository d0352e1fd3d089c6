"""Reference engines: the same chain in Pinocchio, MuJoCo, DART and Exudyn.

Every adapter has the shape of :class:`references.base.Engine` (build from a Case or Chain;
``qdd``, ``mass_matrix``, ``bias``, ``energy``, ``tip``, ``simulate``, ``version``, ``limits``).
Every adapter builds every joint the core can express (R and P about/along any axis, U, S),
from the per-joint elementary axes of :func:`joint_axes`. Importing this package imports no
engine: a missing one raises :class:`EngineUnavailable` (naming the package) only when it is
used::

    from redysim import references
    eng = references.get("mujoco")(chain)     # or references.get("mujoco").limits(case)

Kinematic trees (:class:`redysim.Model`, fixed or free base) go to the same engines' tree
adapters (:mod:`references.trees`: ``qdd``, ``mass_matrix``, ``bias``, ``energy``, ``limits`` in
the core's coordinates, a free joint's included)::

    eng = references.get("dart")(model)       # = references.tree_engine("dart", model)
    references.get("dart").limits(model)      # = references.TREE_ENGINES["dart"].limits(model)

Closed loops (:class:`redysim.loops.ClosedLoops`: a tree and its cut joints) go to the loop
adapters (:mod:`references.loops`), which close the cuts with each engine's own constraint::

    eng = references.loop_engine("exudyn", loops)   # references.LOOP_ENGINES lists them
    qdd, lam = eng.forward_dynamics(q, v, tau)      # as ClosedLoops.forward_dynamics
"""

from __future__ import annotations

from .base import (
    Axis,
    Engine,
    EngineLimitExceeded,
    EngineUnavailable,
    JointAxes,
    Limits,
    Trajectory,
    joint_axes,
    load_limits,
)
from .dart_engine import DART, DARTTree
from .exudyn_engine import Exudyn, ExudynTree
from .loops import LOOP_ENGINES, LoopEngine, LoopStateUnsupported, loop_engine
from .mujoco_engine import MuJoCo, MuJoCoTree
from .pinocchio_engine import (
    PinocchioABA,
    PinocchioABARyRz,
    PinocchioCRBA,
    PinocchioTreeABA,
    PinocchioTreeABARyRz,
    PinocchioTreeCRBA,
)
from .trees import TreeEngine, TreeJointAxes, tree_class, tree_engine, tree_joints

ENGINES: dict[str, type[Engine]] = {
    cls.name: cls
    for cls in (PinocchioABA, PinocchioABARyRz, PinocchioCRBA, MuJoCo, DART, Exudyn)
}


# the same engines on kinematic trees (redysim.Model), by the same names
TREE_ENGINES: dict[str, type[TreeEngine]] = {
    cls.name: cls
    for cls in (PinocchioTreeABA, PinocchioTreeABARyRz, PinocchioTreeCRBA, MuJoCoTree, DARTTree,
                ExudynTree)
}
assert set(TREE_ENGINES) == set(ENGINES)


def get(name: str) -> type[Engine]:
    """The adapter class registered under ``name`` (see :data:`ENGINES`)."""
    try:
        return ENGINES[name]
    except KeyError:
        raise KeyError(f"no engine {name!r}; known engines: {', '.join(ENGINES)}") from None


__all__ = ["ENGINES", "LOOP_ENGINES", "TREE_ENGINES", "Axis", "Engine", "EngineLimitExceeded",
           "EngineUnavailable", "JointAxes", "Limits", "Trajectory", "TreeEngine",
           "LoopEngine", "LoopStateUnsupported", "TreeJointAxes", "get", "joint_axes",
           "load_limits", "loop_engine", "tree_class", "tree_engine",
           "tree_joints", "DART", "DARTTree", "Exudyn", "ExudynTree", "MuJoCo", "MuJoCoTree",
           "PinocchioABA", "PinocchioABARyRz", "PinocchioCRBA", "PinocchioTreeABA",
           "PinocchioTreeABARyRz", "PinocchioTreeCRBA"]
