"""Reference engines: the same chain in Pinocchio, MuJoCo, DART and Exudyn.

Every adapter has the shape of :class:`references.base.Engine` (build from a Case or Chain;
``qdd``, ``mass_matrix``, ``bias``, ``energy``, ``tip``, ``simulate``, ``version``, ``limits``).
Every adapter builds every joint the core can express (R and P about/along any axis, U, S),
from the per-joint elementary axes of :func:`joint_axes`. Importing this package imports no
engine: a missing one raises :class:`EngineUnavailable` (naming the package) only when it is
used::

    from redysim import references
    eng = references.get("mujoco")(chain)     # or references.get("mujoco").limits(case)
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
from .dart_engine import DART
from .exudyn_engine import Exudyn
from .mujoco_engine import MuJoCo
from .pinocchio_engine import PinocchioABA, PinocchioABARyRz, PinocchioCRBA

ENGINES: dict[str, type[Engine]] = {
    cls.name: cls
    for cls in (PinocchioABA, PinocchioABARyRz, PinocchioCRBA, MuJoCo, DART, Exudyn)
}


def get(name: str) -> type[Engine]:
    """The adapter class registered under ``name`` (see :data:`ENGINES`)."""
    try:
        return ENGINES[name]
    except KeyError:
        raise KeyError(f"no engine {name!r}; known engines: {', '.join(ENGINES)}") from None


__all__ = ["ENGINES", "Axis", "Engine", "EngineLimitExceeded", "EngineUnavailable", "JointAxes",
           "Limits", "Trajectory", "get", "joint_axes", "load_limits", "DART", "Exudyn", "MuJoCo",
           "PinocchioABA", "PinocchioABARyRz", "PinocchioCRBA"]
