"""The reference engines on kinematic trees: the same :class:`redysim.Model` in every engine.

A tree adapter builds the Model's own tree from its arrays (``parent``, ``placement_R``,
``placement_p``, the per-DOF tables ``dof_kind``/``dof_u``, ``mass``, ``com``, ``inertia_com``,
``gravity``), never from the file the Model was read from, so every engine runs the identical
system: the one the core runs. It answers in the core's names, units and coordinates:

=========================  ==================================================================
``qdd(q, v, tau=None)``    vdot from I(q) vdot = phi(q, v, tau), length ``model.n_v``
``mass_matrix(q)``         the GIM I(q), (n_v, n_v), symmetric
``bias(q, v)``             phi with tau = 0: -(C(q, v) v + gravity terms), as ``redysim.phi``
``energy(q, v)``           (T, V) in J; V = -sum m_k g . r_Ck
``version``, ``limits(model)``, ``available()``: as the chain adapters' (:mod:`.base`)
=========================  ==================================================================

q has length ``model.n_q`` and v ``model.n_v``, in the core's order (bodies in the Model's order,
each joint's axes in order). A free joint (a floating base) is the core's: q = (x, y, z, qw, qx,
qy, qz), the body origin's world position and a unit quaternion (w first; it is normalised here,
as the core reads only its direction), v = (v_world, w_body): the origin's velocity in the WORLD
frame and the angular velocity in the BODY frame (MuJoCo's convention). Every engine with other
coordinates is converted both ways in its adapter, by one rule (:class:`FreeBlock`): with y the
engine's velocity coordinates of the joint in the core's slot order, v = B y with B orthogonal
(a rotation of the linear or the angular part), so

    y = B^T v,  tau_engine = B^T tau,  I = B I_engine B^T,  vdot = B ydot + c,
    phi = B phi_engine + I c,          c = (dB/dt) y,

which follows from I_engine ydot = tau_engine + phi_engine and v = B y (T, V are invariant).
Each engine's module docstring says what its B and c are.

The joints: :func:`tree_joints` reads each body's joint from the Model's tables, as
:func:`.base.joint_axes` reads a chain's: its type, its elementary axes (:class:`.base.Axis`, in
the frame the axes before it leave; U = R about y then the turned z, S = U then the turned x),
its parent body and its placement (R, p) in the parent's frame. Engines are looked up by the
chain adapters' names: :func:`tree_engine` ("mujoco", model), or ``references.get(name)(model)``
and ``references.get(name).limits(model)``, which hand a Model to the tree adapter.

``limits(model)`` decides before anything is built: a body or joint the engine has no
construction for (:meth:`TreeEngine.unsupported`, with the engine's own words), or a size beyond
the measured limits of ``references/limits.toml`` (DOF = n_v; links = bodies, or the tree's depth
for MuJoCo, whose limit is the depth of its body tree).
"""

from __future__ import annotations

from typing import Any, ClassVar, NamedTuple

import numpy as np

from redysim.model import FREE, Model
from redysim.rbda import quaternion_matrix

from .base import (
    KIND_NAMES,
    TREE_ADAPTERS,
    Axis,
    EngineLimitExceeded,
    EnginePackage,
    Limits,
    import_engine,
    load_limits,
    tree_adapter,
)


class TreeJointAxes(NamedTuple):
    """Body k's joint: its type (R, P, U, S or free), its elementary axes in order (none for a
    free joint), the parent body (-1: the world) and the placement (R (3, 3), p (3,)) of the
    joint's frame in the parent's frame."""

    type: str
    axes: tuple[Axis, ...]
    parent: int
    R: np.ndarray
    p: np.ndarray

    def describe(self) -> str:
        if self.type == FREE:
            return "free"
        return f"{self.type} = " + " then ".join(a.describe() for a in self.axes)


def tree_joints(model: Model) -> list[TreeJointAxes]:
    """Per body, its joint (:class:`TreeJointAxes`) from the Model's own per-DOF tables. Raises
    ValueError on a DOF kind the adapters do not model."""
    out = []
    for k, jtype in enumerate(model.joint_types):
        axes = []
        if jtype != FREE:
            for i in range(int(model.joint_voff[k]), int(model.joint_voff[k + 1])):
                kind = KIND_NAMES.get(int(model.dof_kind[i]))  # R or P; a BALL is not one
                if kind is None:
                    raise ValueError(f"body {k} ({model.body_names[k]}): DOF kind "
                                     f"{int(model.dof_kind[i])} outside a free joint")
                u = tuple(float(x) for x in model.dof_u[i])
                plus = [j for j in range(3) if u[j] == 1.0 and u[j - 1] == u[j - 2] == 0.0]
                axes.append(Axis(kind, u, plus[0] if plus else None))
        out.append(TreeJointAxes(jtype, tuple(axes), int(model.parent[k]),
                                 np.array(model.placement_R[k], dtype=float),
                                 np.array(model.placement_p[k], dtype=float)))
    return out


def tree_depth(model: Model) -> int:
    """The number of bodies on the longest path from the world to a leaf."""
    depth = np.zeros(model.n_bodies, dtype=np.int64)
    for k, p in enumerate(model.parent):
        depth[k] = 1 if p < 0 else depth[p] + 1
    return int(depth.max())


def depth_first(model: Model) -> list[int]:
    """The bodies in depth-first pre-order (each body's subtree follows it contiguously;
    children in the Model's order). The Model's own order only puts parents first."""
    children: list[list[int]] = [[] for _ in range(model.n_bodies)]
    roots = []
    for k, p in enumerate(model.parent):
        (roots if p < 0 else children[p]).append(k)
    order, stack = [], roots[::-1]
    while stack:
        k = stack.pop()
        order.append(k)
        stack.extend(children[k][::-1])
    return order


def free_rotation(q, qs: int) -> np.ndarray:
    """The rotation of the free joint whose configuration starts at ``q[qs]`` (its quaternion,
    w first, normalised)."""
    quat = np.asarray(q[qs + 3:qs + 7], dtype=float)
    return quaternion_matrix(*(quat / np.linalg.norm(quat)))


class FreeBlock(NamedTuple):
    """One free joint's conversion at a state (module docstring): the core's velocity slots
    ``vs:vs + 6`` are ``B y`` and its acceleration ``B ydot + c``, y the engine's velocity
    coordinates of the joint gathered into the core's slot order."""

    vs: int
    B: np.ndarray
    c: np.ndarray


def _check_model(model) -> Model:
    if not isinstance(model, Model):
        raise TypeError(f"expected a redysim.Model, got {type(model).__name__} (a Chain: use "
                        f"the chain adapters, or Model.from_chain(chain))")
    return model


class TreeEngine(EnginePackage):
    """Base class of the tree adapters (module docstring). A subclass sets ``name``,
    ``package``, ``module`` and implements ``_build`` and the raw hooks, which take and return
    the ENGINE's coordinates; the public methods here convert.

    Hooks: ``_engine_state(q, v)`` -> (state, blocks): whatever the raw hooks need to set the
    configuration (engine-specific), and one :class:`FreeBlock` per free joint; and, on that
    state, ``_raw_qdd(state, y, tau_e)``, ``_raw_mass_matrix(state)``, ``_raw_bias(state, y)``,
    ``_raw_energy(state, y)``, with y and tau_e engine-ordered vectors of length ``n_e``.
    ``self.eidx`` (n_v,): the engine index of each of the core's velocity slots.
    """

    name: ClassVar[str] = ""
    package: ClassVar[str] = ""
    module: ClassVar[str] = ""
    depth_limited: ClassVar[bool] = False  # limits.toml's max_links is a body-tree depth

    def __init_subclass__(cls, **kwargs: Any):
        super().__init_subclass__(**kwargs)
        if cls.name:
            TREE_ADAPTERS[cls.name] = cls

    def __init__(self, model: Model, *, check_limits: bool = True):
        self.lib = import_engine(self.name, self.package, self.module)
        self.model = _check_model(model)
        if check_limits:
            lim = self.limits(model)
            if not lim.ok:
                raise EngineLimitExceeded(f"{self.name}: {lim.reason}")
        self.joints = tree_joints(model)
        self.eidx = np.arange(model.n_v)
        self._build()

    # ----------------------------------------------------------------------- limits
    @classmethod
    def limits(cls, model: Model) -> Limits:
        """Can this engine take the tree? Decided from its joints, bodies and size and the
        measured limits in ``references/limits.toml``, before anything is built."""
        model = _check_model(model)
        try:
            joints = tree_joints(model)
        except ValueError as exc:
            return Limits(False, f"{cls.name}: {exc}")
        why = cls.unsupported(model, joints)
        if why:
            return Limits(False, f"{cls.name}: {why}")
        entry = load_limits()["engine"][cls.name]
        n = model.n_v
        links = tree_depth(model) if cls.depth_limited else model.n_bodies
        max_dof, max_links = int(entry["max_dof"]), int(entry.get("max_links", 10**9))
        if n > max_dof or links > max_links:
            what = (f"{n:,} DOF" if n > max_dof else
                    f"a body tree {links:,} deep" if cls.depth_limited else f"{links:,} bodies")
            return Limits(False, f"{cls.name}: {what} exceeds its limit on this machine "
                                 f"(max {max_dof:,} DOF, {max_links:,} links): {entry['stops']}")
        return Limits(True, "")

    @classmethod
    def unsupported(cls, model: Model, joints: list[TreeJointAxes]) -> str:
        """Why this engine cannot build the tree ("" when it can)."""
        return ""

    # ----------------------------------------------------------------------- conversions
    def _check(self, name, x, n, optional=False):
        if x is None:
            if optional:
                return None
            raise ValueError(f"{name} is required")
        a = np.asarray(x, dtype=float)
        if a.shape != (n,):
            raise ValueError(f"{name} has shape {a.shape}; the model has "
                             f"{'n_q' if name == 'q' else 'n_v'} = {n}")
        return a

    def _to_engine(self, x, blocks) -> np.ndarray:
        """A velocity or force in the core's coordinates as the engine's (B^T per free joint,
        then scattered to the engine's order)."""
        g = np.array(x, dtype=float)
        for b in blocks:
            g[b.vs:b.vs + 6] = b.B.T @ g[b.vs:b.vs + 6]
        y = np.zeros(self.n_e)
        y[self.eidx] = g
        return y

    def _from_engine(self, y, blocks) -> np.ndarray:
        """An engine-ordered velocity-like vector in the core's coordinates (B per free joint)."""
        g = np.asarray(y, dtype=float)[self.eidx].copy()
        for b in blocks:
            g[b.vs:b.vs + 6] = b.B @ g[b.vs:b.vs + 6]
        return g

    def _gim_from_engine(self, M, blocks) -> np.ndarray:
        M = np.asarray(M, dtype=float)[np.ix_(self.eidx, self.eidx)].copy()
        if blocks:
            T = np.eye(self.model.n_v)
            for b in blocks:
                T[b.vs:b.vs + 6, b.vs:b.vs + 6] = b.B
            M = T @ M @ T.T
        return M

    @staticmethod
    def _c(n, blocks) -> np.ndarray:
        c = np.zeros(n)
        for b in blocks:
            c[b.vs:b.vs + 6] = b.c
        return c

    @property
    def n_e(self) -> int:
        """Length of the engine's velocity vector."""
        return self.model.n_v

    # ----------------------------------------------------------------------- public API
    def qdd(self, q, v, tau=None) -> np.ndarray:
        m = self.model
        q, v = self._check("q", q, m.n_q), self._check("v", v, m.n_v)
        tau = self._check("tau", tau, m.n_v, optional=True)
        state, blocks = self._engine_state(q, v)
        y = self._to_engine(v, blocks)
        tau_e = None if tau is None else self._to_engine(tau, blocks)
        return self._from_engine(self._raw_qdd(state, y, tau_e), blocks) + self._c(m.n_v, blocks)

    def mass_matrix(self, q) -> np.ndarray:
        m = self.model
        q = self._check("q", q, m.n_q)
        state, blocks = self._engine_state(q, np.zeros(m.n_v))
        return self._gim_from_engine(self._raw_mass_matrix(state), blocks)

    def bias(self, q, v) -> np.ndarray:
        m = self.model
        q, v = self._check("q", q, m.n_q), self._check("v", v, m.n_v)
        state, blocks = self._engine_state(q, v)
        y = self._to_engine(v, blocks)
        phi = self._from_engine(self._raw_bias(state, y), blocks)
        if blocks:
            phi = phi + self._gim_from_engine(self._raw_mass_matrix(state), blocks) @ \
                self._c(m.n_v, blocks)
        return phi

    def energy(self, q, v) -> tuple[float, float]:
        m = self.model
        q, v = self._check("q", q, m.n_q), self._check("v", v, m.n_v)
        state, blocks = self._engine_state(q, v)
        T, V = self._raw_energy(state, self._to_engine(v, blocks))
        return float(T), float(V)

    def __repr__(self) -> str:
        m = self.model
        return f"{type(self).__name__}({m.name!r}, {m.n_bodies} bodies, n_v = {m.n_v})"

    # ----------------------------------------------------------------------- hooks
    def _build(self) -> None:
        raise NotImplementedError

    def _engine_state(self, q, v):
        raise NotImplementedError

    def _raw_qdd(self, state, y, tau_e):
        raise NotImplementedError

    def _raw_mass_matrix(self, state):
        raise NotImplementedError

    def _raw_bias(self, state, y):
        raise NotImplementedError

    def _raw_energy(self, state, y):
        raise NotImplementedError


def tree_class(name: str) -> type[TreeEngine]:
    """The tree adapter registered under ``name`` (the chain adapters' names; the package's
    ``__init__`` imports every engine module, which registers it)."""
    return tree_adapter(name)


def tree_engine(name: str, model: Model, *, check_limits: bool = True) -> TreeEngine:
    """Engine ``name`` built on ``model`` (raises EngineLimitExceeded with the reason when its
    ``limits`` refuse the model, EngineUnavailable when its package is missing)."""
    return tree_class(name)(model, check_limits=check_limits)
