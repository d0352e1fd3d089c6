"""External loads: a constant world-frame force at the chain's tip, as joint forces and energy.

A force F [N] acting at the tip p (the distal end of the last link, what :func:`redysim.tip`
returns) does the virtual work F . dp = F . J(q) dq, so its generalized force is tau = J^T F,
one entry per DOF (what :func:`redysim.forward_dynamics` takes as ``tau``): for a revolute axis
with world direction e through its joint's origin O_k, tau = e . ((p - O_k) x F); for a
prismatic one, tau = e . F. A constant F is conservative, with
potential -F . p(q), so T + V - F . p is conserved by the motion it drives (the energy check of
a scene "a chain pulled at its end").

Both come from one position pass of the kinematics: the world axes are the motion-subspace
columns P = [e; 0] (revolute) or [0; e] (prismatic) that it leaves in ``ws.oP``, so
tau = P_ang . ((p - O_k) x F) + P_lin . F needs no branch on the joint's type: O(n), exact.
"""

from __future__ import annotations

import math
import reprlib

import numpy as np

from redysim.algorithms.dynamics import _run_kinematics, _ws, check_state, overflow_error
from redysim.algorithms.vectors import cross
from redysim.algorithms.workspace import Workspace
from redysim.errors import FieldError, StateError
from redysim.model.parts import numeric_array
from redysim.model.tree import Model


def check_force(force) -> np.ndarray:
    """``force`` as a finite float 3-vector (world frame, N), or StateError naming it."""
    arr = numeric_array(force)
    if arr is None or arr.shape != (3,):
        shape = "" if arr is None else f", got shape {arr.shape}"
        raise StateError(f"force = {reprlib.repr(force)}: must be a vector of 3 numbers "
                         f"[Fx, Fy, Fz] in N, world frame{shape}")
    if not np.isfinite(arr).all():
        raise StateError(f"force = {reprlib.repr(force)}: not finite (no NaN or Inf)")
    return arr


def _inputs(chain: Model, q, force, caller: str) -> tuple[np.ndarray, np.ndarray]:
    """(q, F) checked, for a chain (a tree has no single tip)."""
    if not isinstance(chain, Model) or chain.chain_layout is not None:
        raise FieldError(caller, "chain", getattr(chain, "name", type(chain).__name__),
                         "must be a chain of links, a redysim.Chain (the tip is the distal end "
                         "of its last link)")
    return check_state(chain, "q", q), check_force(force)


def _tip_position(chain: Model, q: np.ndarray, ws: Workspace | None
                  ) -> tuple[np.ndarray, Workspace]:
    """The position pass of the kinematics; returns (p_tip, the workspace it filled)."""
    ws = _ws(chain, ws)
    _run_kinematics(chain, ws, q, ws.zeros, ws.zeros, ws.no_accel)
    k = chain.n_links - 1
    with np.errstate(over="ignore", invalid="ignore"):  # overflow is reported by the callers
        return ws.oO[k] + chain.length[k] * ws.oR[k][:, 0], ws


def tip_force_torques(chain: Model, q, force, *, ws: Workspace | None = None) -> np.ndarray:
    """tau = J_tip(q)^T F (n,): the joint forces of a constant world-frame force ``force`` [N]
    acting at the chain's tip (module docstring). Pass it, plus any other joint forces, as the
    ``tau`` of :func:`redysim.forward_dynamics`. ``chain``: a serial chain of links (a Chain, or
    a Model with a chain's layout), the tip the distal end of its last link; FieldError for any
    other model (a tree has no single tip)."""
    q, F = _inputs(chain, q, force, "tip_force_torques")
    p, ws = _tip_position(chain, q, ws)
    # each DOF's moment arm p - O_k, O_k its joint's origin: every revolute axis passes through
    # it (no joint type has a prismatic axis before a revolute one), and a prismatic column has
    # no angular half to multiply its arm
    link_of_dof = np.repeat(np.arange(chain.n_links), np.diff(chain.joint_qoff))
    with np.errstate(over="ignore", invalid="ignore"):  # reported just below
        arm = p - ws.oO[link_of_dof]
        tau = np.einsum("ij,ij->i", ws.oP[:, :3], cross(arm, F)) + ws.oP[:, 3:] @ F
    if not np.isfinite(tau).all():
        raise overflow_error("tau", q=q, force=F)
    return tau


def tip_force_potential(chain: Model, q, force, *, ws: Workspace | None = None) -> float:
    """-F . p_tip(q) [J]: the potential of a constant force at the tip, zero with the tip at the
    origin, so that T + V + this is conserved (V from :func:`redysim.energy`). ``chain``: as
    :func:`tip_force_torques` takes it (a serial chain of links)."""
    q, F = _inputs(chain, q, force, "tip_force_potential")
    p, _ = _tip_position(chain, q, ws)
    with np.errstate(over="ignore", invalid="ignore"):
        potential = -float(F @ p)
    if not math.isfinite(potential):
        raise overflow_error("the tip force's potential", q=q, force=F)
    return potential
