"""Closed forms that no engine supplies, for the scenarios whose truth they are.

- :func:`hanging_mode`: a planar chain hanging straight down, its k-th small-oscillation
  frequency and mode shape from the linearised kinetic and potential energies written out by
  hand (not from the core's mass matrix): released from that shape at rest with a small
  amplitude, the tip moves as x0 cos(omega t) to second order in the amplitude
  (cases/scenarios/HANGING-MODE.toml; :func:`mode_deviation` measures a run against it).
- :func:`pinned_catenary`: a chain of equal rods pinned at both ends, its static equilibrium
  (:func:`redysim.algorithms.linkages.discrete_catenary`, a closed form up to one scalar root),
  which a damped run settles on (cases/scenarios/CATENARY.toml).
- :func:`flip_half_period`: the Dzhanibekov flip's half period (Landau and Lifshitz).

The report's "Scenarios" table and the gates (harness/gates.toml, ``measure = "truth"``) take
their truths from here.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np


def _hanging_matrices(chain) -> tuple[np.ndarray, np.ndarray]:
    """(M, K) of the chain linearised about hanging straight down, in its relative joint
    angles q. With phi_j the angle of link j from the downward vertical (phi = T q, T the lower
    triangle of ones), the horizontal position of link j's centre of mass is
    sum_{i<j} l_i phi_i + c_j phi_j to first order, so with B_j the mass below link j

        M_abs[j, j] = m_j c_j^2 + I_j + l_j^2 B_j,   M_abs[i, j] = l_i (m_j c_j + l_j B_j) (i < j),
        K_abs = diag(g (m_j c_j + l_j B_j)),

    and M = T^T M_abs T, K = T^T K_abs T (I_j: link j's moment of inertia about its centre of
    mass, about the plane's normal)."""
    if not getattr(chain, "is_planar", False):
        raise ValueError(f"{chain.name}: a hanging chain's modes need a planar chain of "
                         "revolute joints")
    if np.abs(chain.com[:, 1:]).max() > 0:
        raise ValueError(f"{chain.name}: the closed form takes centres of mass on the links' "
                         "axes")
    m, l, c = chain.mass, chain.length, chain.com[:, 0]
    inertia = chain.inertia_com[:, 2, 2]
    below = _mass_below(chain)
    w = m * c + l * below
    n = chain.n_dof
    upper = np.triu(np.outer(l, w), 1)  # [i, j] = l_i w_j for i < j
    m_abs = upper + upper.T + np.diag(m * c ** 2 + inertia + l ** 2 * below)
    T = np.tril(np.ones((n, n)))
    return T.T @ m_abs @ T, hanging_stiffness(chain)


def _mass_below(chain) -> np.ndarray:
    """B_j: the mass of the links after link j."""
    return np.concatenate((np.cumsum(chain.mass[::-1])[::-1][1:], [0.0]))


def hanging_stiffness(chain) -> np.ndarray:
    """K of the chain hanging straight down, in its relative joint angles (exact): the
    potential's Hessian in the absolute angles is diag(w), w_j = g (m_j c_j + l_j B_j), and
    phi = T q, so K = T^T diag(w) T, K[a, b] = the sum of w_j over j >= max(a, b) (O(n^2))."""
    if not getattr(chain, "is_planar", False):
        raise ValueError(f"{chain.name}: a hanging chain's modes need a planar chain of "
                         "revolute joints")
    w = -float(chain.gravity[1]) * (chain.mass * chain.com[:, 0] + chain.length
                                    * _mass_below(chain))
    tail = np.cumsum(w[::-1])[::-1]  # the sum of w over j' >= j
    idx = np.arange(chain.n_dof)
    return tail[np.maximum(idx[:, None], idx[None, :])]


def hanging_straight(chain) -> np.ndarray:
    """The configuration hanging straight down (gravity -Y): joint 1 at -90 degrees."""
    q = np.zeros(chain.n_dof)
    q[0] = -math.pi / 2
    return q


def hanging_mode(chain, k: int = 1) -> tuple[float, np.ndarray]:
    """(omega_k [rad/s], shape): the k-th lowest frequency of the chain hanging straight down
    and its mode shape in relative joint angles, scaled so that its largest entry is +1."""
    from scipy.linalg import eigh

    if not 1 <= k <= chain.n_dof:
        raise ValueError(f"mode {k!r}: the chain has modes 1..{chain.n_dof}")
    M, K = _hanging_matrices(chain)
    lam, vec = eigh(K, M, subset_by_index=[k - 1, k - 1])
    shape = vec[:, 0] / vec[np.argmax(np.abs(vec[:, 0])), 0]
    return math.sqrt(float(lam[0])), shape


def mode_deviation(chain, q0: np.ndarray, t: np.ndarray, tip_x: np.ndarray,
                   k: int = 1) -> float:
    """max over the samples of |tip_x(t) - x0 cos(omega_k t)| / |x0|: how far a run released
    at rest from mode k's shape strays from that mode's closed-form motion (x0 the tip's
    horizontal offset at t = 0, from q0)."""
    omega, _ = hanging_mode(chain, k)
    phi = np.cumsum(q0) + math.pi / 2  # absolute angles from the downward vertical
    x0 = float(np.sum(chain.length * np.sin(phi)))
    if x0 == 0.0:
        raise ValueError("the run starts with its tip on the vertical: no mode to follow")
    t = np.asarray(t, dtype=float)
    return float(np.abs(np.asarray(tip_x) - x0 * np.cos(omega * t)).max() / abs(x0))


def pinned_chain_of(model) -> SimpleNamespace:
    """n, length, mass and span of a chain of equal rods pinned at (0, 0) and by its one cut
    joint at (span, 0) (a linkage such as cases/loops/pinned_chain_100.toml), as
    :func:`redysim.algorithms.linkages.discrete_catenary` takes them; ValueError for a model
    that is not one."""
    n = model.n_bodies
    if len(model.cuts) != 1 or any(t != "R" for t in model.joint_types):
        raise ValueError(f"{model.name}: not a chain of revolute joints with one cut joint")
    cut = model.cuts[0]
    lengths = np.linalg.norm(model.placement_p[1:], axis=1)
    length = float(model.placement_p[1][0]) if n > 1 else math.nan
    ok = (np.allclose(model.mass, model.mass[0], rtol=1e-12)
          and np.allclose(lengths, length, rtol=1e-12)
          and np.allclose(model.com, [length / 2, 0.0, 0.0], rtol=1e-12, atol=1e-15)
          and np.allclose(model.placement_p[0], 0.0) and cut.body_a == n - 1 and cut.body_b < 0
          and np.allclose(cut.point_a, [length, 0.0, 0.0], rtol=1e-12)
          and abs(cut.point_b[1]) < 1e-15)
    if not ok:
        raise ValueError(f"{model.name}: the closed form takes equal rods (centre of mass at "
                         "the middle) hung from the origin, the last one's end pinned to a "
                         "ground point on the X axis")
    return SimpleNamespace(n=n, length=length, mass=float(model.mass[0]),
                           span=float(cut.point_b[0]))


def pinned_catenary(model) -> np.ndarray:
    """The joint angles of the pinned chain's static equilibrium (:func:`pinned_chain_of`),
    under the model's gravity (along -Y)."""
    from redysim.algorithms.linkages import discrete_catenary

    g = np.asarray(model.gravity, dtype=float)
    if g[0] != 0.0 or g[2] != 0.0 or not g[1] < 0:
        raise ValueError(f"{model.name}: the catenary's closed form takes gravity along -Y")
    return discrete_catenary(pinned_chain_of(model), gravity=-float(g[1]))


def catenary_point(model, frame: str) -> np.ndarray:
    """Where ``frame`` of the pinned chain is on its static equilibrium (:func:`pinned_catenary`):
    its world position [m] there."""
    from redysim.algorithms.dynamics import frame_motion

    q = pinned_catenary(model)
    return frame_motion(model, q, np.zeros(model.n_v), frame=frame).position


def flip_half_period(I1: float, I2: float, I3: float, w) -> float:
    """Half the period of a torque-free body's spin about its middle principal axis (moments
    I1 < I2 < I3, body-frame angular velocity w at any instant): 2 K(k) / lambda, the time
    between the sign changes of w_2 (Landau and Lifshitz, Mechanics, section 37)."""
    from scipy.special import ellipk

    E2 = I1 * w[0] ** 2 + I2 * w[1] ** 2 + I3 * w[2] ** 2  # 2 E
    L2 = (I1 * w[0]) ** 2 + (I2 * w[1]) ** 2 + (I3 * w[2]) ** 2
    if L2 > E2 * I2:
        lam = math.sqrt((I3 - I2) * (L2 - E2 * I1) / (I1 * I2 * I3))
        m = (I2 - I1) * (E2 * I3 - L2) / ((I3 - I2) * (L2 - E2 * I1))
    else:
        lam = math.sqrt((I2 - I1) * (E2 * I3 - L2) / (I1 * I2 * I3))
        m = (I3 - I2) * (L2 - E2 * I1) / ((I2 - I1) * (E2 * I3 - L2))
    return 2.0 * float(ellipk(m)) / lam
