"""A run's physics as one object: the model, the forces and constraints on it, what a stepper
calls.

:class:`System` keeps the contract every stepper sees
(:class:`redysim.integrators.protocol.Dynamics`): the state derivative into a buffer, the
projection after a step, and, when the physics is compiled, its compiled contract
(:mod:`redysim.algorithms._kernels.system`), which the compiled stepping inlines and which the
Python methods here call too: a force or a constraint is written once, and both steppers see it
in the same bits.

The state is y = (q, v); dq/dt = v, but a free or ball joint's quaternion, which moves as q (x)
[0; w_body] / 2 and is projected back onto the unit sphere after every step (the kernels read a
quaternion's direction only, so a stage's slightly-off one is harmless). Forces: viscous joint
damping, joint springs, a constant force at a chain's tip, and a Python function ``tau(t, q,
v)`` of the caller's; constraints: the model's couplings (mimic joints) and closed loops. The
accelerations come from the core's forward dynamics (RGE-A; GE-N or RGE-N by ``method``) or
from a provider ``qdd(q, v, tau)`` (a reference engine's). Anything Python (``tau``, ``qdd``, a
method other than RGE-A) makes the derivative Python: such a system is stepped in Python only.

The work of the forces without a potential in the energy (:attr:`System.work_forces`: the
viscous damping, and a caller's ``tau`` given without ``potential``) can be stepped with the
motion as one more component, y = (q, v, W), dW/dt = v . tau_nc (:meth:`System.initial_state`
appends it; the derivative writes its rate when y has it), so that E(t) - W(t) = E(0) along a
run to the integrator's accuracy. The tip force, the body forces, gravity compensation and the
springs have potentials counted in :meth:`System.energy_and_com`; the loops' and couplings'
constraint forces do no work.
"""

from __future__ import annotations

import math

import numpy as np

from redysim.algorithms._kernels import system as K
from redysim.algorithms._kernels.constraints import no_loops
from redysim.algorithms._kernels.energy import energy as _energy
from redysim.algorithms._kernels.kinematics import kinematics as _kinematics
from redysim.algorithms.dynamics import (
    check_coupled,
    check_state,
    energy,
    forward_dynamics,
)
from redysim.algorithms.loads import check_force, tip_force_potential, tip_force_torques
from redysim.algorithms.methods import METHODS
from redysim.algorithms.workspace import Workspace
from redysim.errors import SettingsError, StateError
from redysim.model import door
from redysim.model.tree import BALL_JOINT, FREE, MAX_GRAVCOMP, QUATERNION_JOINTS, Model

QUATERNION_TOL = 1e-6  # | |q0's quaternion| - 1 | allowed (then normalised); more is refused
NUMBERS = (int, float, np.integer, np.floating)  # a setting's number types (not bool)


def _shown(x) -> str:
    """A provider's answer in a message: its type, and its value when short."""
    text = repr(x)
    return text if len(text) <= 60 else f"a value of type {type(x).__name__}"


class System:
    """The physics of a run of ``model`` (module docstring).

    ``damping``: a viscous torque -damping * v at every joint, a number or one per velocity
    coordinate [N m s] (0: none). ``stiffness`` (one per velocity coordinate, or a number) and
    ``spring_ref`` (the rest positions, default zeros): joint springs, torque -stiffness (q -
    spring_ref) [N m / rad], on joints whose coordinates are their velocities' (not a free
    joint's). ``tip_force``: a constant world force [N] (3,) at a chain's tip (its torques J^T F;
    its potential -F . p_tip counted in the energy). ``body_forces``: constant world forces at
    points of bodies, each ``(body name, force (3,) [N], point (3,) [m] in the body's frame)``;
    ``gravcomp``: gravity compensation, the fraction of each body's weight held up at its centre
    of mass (a number, one per body, or body name -> fraction; MuJoCo's body ``gravcomp``): both
    are constant forces, their potentials counted in the energy. ``tau(t, q, v) -> (n_v,)``:
    generalized forces of the caller's, with ``potential(q)`` their potential energy [J] when
    they have one.
    ``loops``: a :class:`redysim.algorithms.loops.ClosedLoops` of the model (by default, a model
    with cut joints gets its own). ``qdd(q, v, tau) -> (n_v,)``: the accelerations' provider
    instead of the core's forward dynamics by ``method`` ("rge-a", "ge-n", "rge-n"); with loops,
    the constrained accelerations. ``source`` names the caller in messages.

    The model's own passive elements (:attr:`Model.damping`, :attr:`Model.stiffness` with
    :attr:`Model.spring_ref`, :attr:`Model.gravcomp`: its file's) are always applied; the settings
    add to them (``damping`` and ``gravcomp`` add to the model's coefficients; ``stiffness``
    with ``spring_ref`` is a second spring on each joint, the two summed as one of stiffness
    k1 + k2 at rest (k1 r1 + k2 r2) / (k1 + k2), each one's potential counted in the energy).
    A run without them: ``System(model.without_passive())``. :attr:`additions` lists the
    settings only (an engine holds the model's own in its model).

    Bad settings raise :class:`~redysim.errors.SettingsError` naming them.
    """

    def __init__(self, model: Model, *, damping=0.0, stiffness=None, spring_ref=None,
                 tip_force=None, body_forces=(), gravcomp=None, tau=None, potential=None,
                 loops=None, qdd=None, method: str = "rge-a", source: str = "simulate"):
        door.require_model(model, source)
        for key, f in (("tau", tau), ("potential", potential), ("qdd", qdd)):
            if f is not None and not callable(f):
                raise SettingsError(source, key, f, "must be None or a callable (" + {
                    "tau": "tau(t, q, v) -> (n_v,)", "potential": "potential(q) -> J",
                    "qdd": "qdd(q, v, tau) -> (n_v,)"}[key] + ")")
        if not isinstance(method, str) or method not in METHODS:
            raise SettingsError(source, "method", method,
                                f"unknown; choose one of {', '.join(METHODS)}")
        if isinstance(body_forces, str | bytes | dict) or not hasattr(body_forces, "__iter__"):
            raise SettingsError(source, "body_forces", body_forces, "must be a list of (body "
                                "name, force (3,) [N], point (3,) [m] in the body's frame), "
                                "() for none")
        body_forces = list(body_forces)
        self.model, self.source = model, source
        self.n_q, self.n_v = model.n_q, model.n_v
        self.size = self.n_q + self.n_v
        self.motion_size = self.size  # y = (q, v); a work W rides after it (module docstring)
        self.tau, self.potential, self.provider, self.method = tau, potential, qdd, method
        if loops is None and model.cuts:  # a closed mechanism: its loops closed
            from redysim.algorithms.loops import ClosedLoops

            loops = ClosedLoops(model, source=source)
        if loops is not None and getattr(loops, "model", None) is not model:
            raise SettingsError(source, "loops", type(loops).__name__, "must be the "
                                "ClosedLoops of the model simulated (ClosedLoops(model, cuts))")
        self.loops = loops
        added_damping = _per_dof(source, "damping", damping, self.n_v, "the viscous torque "
                                 "-damping * v at every joint [N m s] (0: none)")
        added_stiffness = _per_dof(source, "stiffness", 0.0 if stiffness is None else stiffness,
                                   self.n_v, "a joint spring's torque -stiffness (q - "
                                   "spring_ref) [N m / rad] (0: none)")
        added_ref = np.zeros(self.n_v) if spring_ref is None else _vector(
            source, "spring_ref", spring_ref, self.n_v)
        self._added = {"damping": bool(added_damping.any()),
                       "stiffness": bool(added_stiffness.any()),
                       "gravcomp": gravcomp is not None and bool(np.any(_gravcomp_factors(
                           source, model, gravcomp))),
                       "body_forces": len(body_forces) > 0}
        # the model's own first, then the settings' (a model without them: the settings' bits)
        self.damping = (model.damping + added_damping) if model.damping.any() else added_damping
        # the springs, each (stiffness, rest) kept for the energy; summed as one for the force
        self.springs = [(k, r) for k, r in ((model.stiffness, model.spring_ref),
                                            (added_stiffness, added_ref)) if k.any()]
        if len(self.springs) == 2:
            k1, r1 = self.springs[0]
            k2, r2 = self.springs[1]
            self.stiffness = k1 + k2
            with np.errstate(invalid="ignore", divide="ignore"):
                self.spring_ref = np.where(self.stiffness > 0, (k1 * r1 + k2 * r2)
                                           / self.stiffness, 0.0)
        elif self.springs:
            self.stiffness, self.spring_ref = (np.array(a, dtype=float)
                                               for a in self.springs[0])
        else:
            self.stiffness, self.spring_ref = added_stiffness, added_ref
        self.tip_force = _tip_force(source, model, tip_force)
        self.body, self.force, self.point = _body_forces(source, model, body_forces, gravcomp)
        self.ws = Workspace(model)  # the derivative's, and between steps the samples'
        self._layout_free_joints()
        if (self._q_of_v[self.stiffness > 0] < 0).any():
            i = int(np.flatnonzero((self._q_of_v < 0) & (self.stiffness > 0))[0])
            k = int(np.searchsorted(model.joint_voff, i, side="right")) - 1
            raise SettingsError(source, "stiffness", f"{model.joint_types[k]} joint "
                                f"{model.joint_names[k]!r}", "springs act on joints whose "
                                "coordinates are their velocities', not on a free or ball "
                                "joint (its q is a quaternion)")
        self.worst = np.zeros(3)  # [quaternion, residual q, residual v] met before projections
        self.power = np.zeros(1)  # the damping's power at the last forces' call (the kernels')
        self.couplings = K.couplings_of(model) if model.couplings else K.no_couplings()
        self.data, self.extras = self._data(), self._extras()
        compiled = (qdd is None and method == "rge-a" and tau is None
                    and (loops is None or getattr(loops, "bundle", None) is not None)
                    and not (model.couplings and model.is_planar))
        self.kernel = (self.data, self.extras) if compiled else None
        self._nearest = [math.inf, math.nan]  # the loops' least s_min / s_max met, and its t
        self._pinned: tuple | None = None  # the samples' kernels (run_energy_and_com)

    # ----------------------------------------------------------------------- assembly
    def _layout_free_joints(self) -> None:
        """Each free joint's q slot of x and v slot of its linear velocity, each ball joint's q
        slot of its quaternion's w and v slot of w_x; every other coordinate's q and v slots
        (dq/dt = v there)."""
        m = self.model
        qoff, voff = m.joint_qoff, m.joint_voff
        free = [(int(qoff[k]), int(voff[k])) for k, t in enumerate(m.joint_types) if t == FREE]
        ball = [(int(qoff[k]), int(voff[k])) for k, t in enumerate(m.joint_types)
                if t == BALL_JOINT]
        plain_q: list[int] = []
        plain_v: list[int] = []
        for k in range(qoff.shape[0] - 1):
            if m.joint_types[k] not in QUATERNION_JOINTS:
                plain_q.extend(range(qoff[k], qoff[k + 1]))
                plain_v.extend(range(voff[k], voff[k + 1]))
        self.free = free + ball  # the joints whose q moves otherwise than v
        self.free_q = np.array([qs for qs, _ in free], dtype=np.int64)
        self.free_v = np.array([vs for _, vs in free], dtype=np.int64)
        self.ball_q = np.array([qs for qs, _ in ball], dtype=np.int64)
        self.ball_v = np.array([vs for _, vs in ball], dtype=np.int64)
        none = not self.free  # without free and ball joints the arrays stay empty: dq/dt = v
        self.plain_q = np.array([] if none else plain_q, dtype=np.int64)
        self.plain_v = np.array([] if none else plain_v, dtype=np.int64)
        # each velocity coordinate's configuration slot (for springs; -1 on a free or ball joint)
        self._q_of_v = np.full(self.n_v, -1, dtype=np.int64)
        self._q_of_v[plain_v] = plain_q

    def _data(self) -> K.SystemData:
        ws, m = self.ws, self.model
        kind = K.PLANAR if m.is_planar else K.DH if ws.dh else K.RGE_A  # as forward dynamics'
        empty = np.zeros(0)
        springs = bool(self.stiffness.any())
        tip = self.tip_force is not None
        return K.SystemData(
            kind, ws.kernel_f, ws.kernel_i, ws.scratch, self.n_q, ws.zeros, np.zeros(self.n_v),
            # writable copies: the model's own arrays are read-only, another numba type
            np.array(self.tip_force, dtype=float) if tip else empty,
            np.array(m.length, dtype=float) if tip else empty,
            -self.damping if self.damping.any() else empty,
            -self.stiffness if springs else empty,
            self.spring_ref.copy() if springs else empty,
            self._q_of_v.copy() if springs else np.zeros(0, dtype=np.int64),
            self.body, self.force, self.point,
            np.zeros((m.n_bodies if self.body.size else 0, 6)), np.zeros(3),
            self.plain_q, self.plain_v, self.free_q, self.free_v, self.ball_q, self.ball_v,
            self.worst, self.power)

    def _extras(self) -> K.Extras | None:
        """What only some systems have, or None (module docstring of the kernels)."""
        if not (self.model.couplings or self.loops is not None
                or (self.tip_force is not None and not self.model.is_planar)):
            return None
        bundle = None if self.loops is None else self.loops.bundle
        return K.Extras(self.couplings, no_loops() if bundle is None else bundle, np.zeros(3))

    @property
    def compiled(self) -> bool:
        """Whether the derivative is compiled (a compiled stepper may step this system)."""
        return self.kernel is not None

    @property
    def work_forces(self) -> list[str]:
        """The forces whose work W the state can carry (module docstring), by setting name:
        "damping" (the model's and the settings'), "tau" (a caller's, given without
        ``potential``); empty for a conservative system."""
        return [name for name, on in (
            ("damping", bool(self.damping.any())),
            ("tau", self.tau is not None and self.potential is None)) if on]

    @property
    def additions(self) -> list[str]:
        """What this system adds to its model's own dynamics, by setting name (an engine's own
        stepper, which steps the engine's model, refuses them)."""
        return [name for name, on in (
            ("tau", self.tau is not None), ("damping", self._added["damping"]),
            ("stiffness", self._added["stiffness"]), ("tip_force", self.tip_force is not None),
            ("body_forces", self._added["body_forces"]), ("gravcomp", self._added["gravcomp"]),
            ("loops", self.loops is not None)) if on]

    # ----------------------------------------------------------------------- the contract
    def derivative(self, t: float, y: np.ndarray, out: np.ndarray) -> None:
        """dy/dt at (t, y) into ``out`` (n_q + n_v,; with y = (q, v, W), n_q + n_v + 1, the
        work's rate last). Raises StateError (from the checked path, saying why) where qdd is
        not defined or not finite."""
        if self.kernel is not None:
            y = y if y.flags.c_contiguous and y.dtype == np.float64 else np.array(y, dtype=float)
            if K.derivative(self.kernel[0], self.kernel[1], t, y, out):
                return
        self._python_derivative(t, y, out)
        if self.kernel is not None and not np.isfinite(out).all():
            raise StateError(f"{self.source}: qdd not finite at t = {t:.6g}")

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """dy/dt at (t, y), a new array."""
        out = np.empty(np.size(y))
        self.derivative(t, y, out)
        return out

    def project(self, y: np.ndarray, record: bool = True) -> None:
        """Move y = (q, v) back onto the constraints after a step, in place (the loops, then the
        couplings' followers onto their leaders, then each quaternion onto the unit sphere);
        with ``record`` (a step's, not an interpolated sample's), the largest departures met
        are kept in ``worst``."""
        worst = self.worst if record else np.zeros(3)
        nq = self.n_q
        if self.loops is not None:
            end = nq + self.n_v  # (a work W after v untouched)
            y[:nq], y[nq:end], rq, rv = self.loops.project(y[:nq], y[nq:end])
            worst[1], worst[2] = max(worst[1], rq), max(worst[2], rv)
        if self.model.couplings:
            K.project_couplings(self.couplings, nq, y, worst[1:])
        if self.free:
            K.project_quaternions(self.free_q, 3, y, worst)
            K.project_quaternions(self.ball_q, 0, y, worst)

    # ----------------------------------------------------------------------- the pieces
    def forces(self, t: float, q, v) -> np.ndarray | None:
        """The generalized forces at (t, q, v) (n_v,): the system's terms (compiled:
        :func:`redysim.algorithms._kernels.system.generalized_forces`) and ``tau``'s; None when
        there are none."""
        return self.forces_and_power(t, q, v)[0]

    def forces_and_power(self, t: float, q, v) -> tuple[np.ndarray | None, float]:
        """(:meth:`forces`, the power v . tau_nc of :attr:`work_forces` [W]): the damping's
        from the compiled terms, plus v . tau for a ``tau`` without ``potential``."""
        d = self.data
        own, power = None, 0.0
        if d.tip.size or d.damping.size or d.stiffness.size or d.body.size:
            own = np.empty(self.n_v)
            K.generalized_forces(d, self.extras, t, np.ascontiguousarray(q, dtype=float),
                                 np.ascontiguousarray(v, dtype=float), own)
            if self.tip_force is not None and not np.isfinite(own).all():
                tip_force_torques(self.model, q, self.tip_force, ws=self.ws)  # says why
            if d.damping.size:
                power = float(d.power[0])
        if self.tau is None:
            return own, power
        given = self.tau(t, q, v)
        try:  # (a complex answer lost its imaginary part with a warning; a string was a bare
            if np.iscomplexobj(given):  # ValueError naming nothing: hold-out battery 6)
                raise TypeError("complex")
            user = np.asarray(given, dtype=float)
        except (TypeError, ValueError):
            raise StateError(f"{self.source}: the joint forces' provider (tau) returned "
                             f"{_shown(given)}; it must return {self.n_v} real numbers (a "
                             f"float array of shape ({self.n_v},))") from None
        if user.shape != (self.n_v,):
            raise StateError(f"{self.source}: the joint forces' provider (tau) returned shape "
                             f"{user.shape}; {self.model.name!r} has {self.n_v} DOF, so it must "
                             f"return shape ({self.n_v},)")
        if self.potential is None:
            power += float(np.dot(v, user))
        return (user if own is None else own + user), power

    def _python_derivative(self, t, y, out) -> None:
        """dy/dt from the checked Python path: the forces, then qdd (the provider's, the loops',
        the coupled tree's or the core's forward dynamics), then dq/dt."""
        nq, model, end = self.n_q, self.model, self.n_q + self.n_v
        q, v = y[:nq], y[nq:end]
        tau, power = self.forces_and_power(t, q, v)
        if self.provider is not None:
            a = np.asarray(self.provider(q, v, tau), dtype=float)
            if a.shape != (self.n_v,):
                raise StateError(f"{self.source}: the accelerations' provider (qdd) returned "
                                 f"shape {a.shape}; {model.name!r} has {self.n_v} DOF, so it "
                                 f"must return shape ({self.n_v},)")
            out[nq:end] = a
        elif self.loops is not None:
            out[nq:end] = self.loops.forward_dynamics(q, v, tau)
        elif model.couplings and self.method == "rge-a" and not model.is_planar:
            q, v = check_state(model, "q", q), check_state(model, "v", v)
            ws = self.ws
            if K.coupled_qdd(ws.kernel_f, ws.kernel_i, ws.scratch, q, v,
                             ws.zeros if tau is None else tau, out[nq:end]) != 0.0:
                # not finite: the checked path says why (or, finite there, is the answer)
                out[nq:end] = forward_dynamics(model, q, v, tau, self.method)
        else:
            forward_dynamics(model, q, v, tau, self.method, ws=self.ws, out=out[nq:end])
        if len(out) > end:  # y = (q, v, W): the work's rate
            out[end] = power
        if not self.free:
            out[:nq] = y[nq:end]
        else:
            K.configuration_rate(nq, self.plain_q, self.plain_v, self.free_q, self.free_v,
                                 self.ball_q, self.ball_v, np.ascontiguousarray(y, dtype=float),
                                 out)

    def qdd(self, t: float, q, v) -> np.ndarray:
        """The accelerations at (t, q, v) (n_v,): the derivative's."""
        out = np.empty(self.size)
        self.derivative(t, np.concatenate((q, v)), out)
        return out[self.n_q:]

    def energy_and_com(self, q, v) -> tuple[float, np.ndarray]:
        """E = T + V (the model's, and the potentials of the tip force, the springs and
        ``potential``), and the centre of mass from the same kinematics pass."""
        T, V = energy(self.model, q, v, ws=self.ws)
        return self._energy_and_com(q, T, V)

    def run_energy_and_com(self, y: np.ndarray) -> tuple[float, np.ndarray]:
        """:meth:`energy_and_com` at a state y = (q, v[, W]) of a run's own (a sample's), in the
        same bits, without the door's checks of q and v and past numba's dispatch
        (:class:`redysim._jit.Pinned`): y a C-contiguous, writable float64 vector, whose q and v
        slices are of the types the kernels were pinned for. Anything else, a y that is not
        finite, or an energy that is not (an overflow), goes the checked way,
        :meth:`energy_and_com`, which raises the StateError naming it, as it would have."""
        nq, end = self.n_q, self.motion_size
        if not (y.ndim == 1 and y.dtype == np.float64 and y.flags.c_contiguous
                and y.flags.writeable and y.shape[0] >= end
                and math.isfinite(float(y[:end].sum()))):  # (a NaN or an Inf makes it not)
            return self.energy_and_com(y[:nq], y[nq:end])
        q, v, ws = y[:nq], y[nq:end], self.ws
        if self._pinned is None:  # (per system: each holds its own workspace's bundles)
            from redysim._jit import Pinned

            self._pinned = (Pinned(_kinematics), Pinned(_energy))
        kinematics, kinetic_potential = self._pinned
        tree, s, zeros, none, gravity = ws.tree, ws.s, ws.zeros, ws.no_accel, ws.gravity
        # the public energy's kinematics and energy passes (its _run_kinematics), on ws
        kinematics.call((tree, s, zeros, none), tree, q, v, zeros, none, s)
        T, V = kinetic_potential.call((tree, gravity, s), tree, gravity, s, v)
        if not (math.isfinite(T) and math.isfinite(V)):
            return self.energy_and_com(q, v)  # (raises, saying why)
        return self._energy_and_com(q, float(T), float(V))

    def _energy_and_com(self, q, T: float, V: float) -> tuple[float, np.ndarray]:
        """E and the centre of mass from (T, V) and the kinematics pass left in the workspace."""
        ws = self.ws
        tree = ws.tree
        md = np.einsum("kij,kj->ki", ws.oR, tree.mass_com)  # m_k R_k c_k
        com = (tree.mass @ ws.oO + md.sum(axis=0)) / self.model.total_mass
        E = T + V
        if self.tip_force is not None:
            E += tip_force_potential(self.model, q, self.tip_force, ws=ws)
        if self.potential is not None:
            E += self.potential(q)
        if self.body.size:  # -f . p of each constant force, p from the same kinematics pass
            p = ws.oO[self.body] + np.einsum("kij,kj->ki", ws.oR[self.body], self.point)
            E -= float(np.sum(self.force * p))
        for k, r in self.springs:  # each spring's own potential (module docstring)
            dq = np.asarray(q)[self._q_of_v] - r
            E += 0.5 * float(np.sum(k * dq * dq))
        return E, com

    # ----------------------------------------------------------------------- a run's start
    def initial_state(self, q0=None, v0=None, *, second_order: bool = False,
                      work: bool = True) -> np.ndarray:
        """y0 = (q0, v0), checked (StateError naming what is wrong) and projected onto the
        constraints: q0 by default the model's own configuration (:meth:`Model.initial`), v0
        zeros; with ``work`` and :attr:`work_forces` (and not ``second_order``), y0 = (q0, v0,
        W0 = 0), the work stepped with the motion (module docstring). A free or ball joint's
        quaternion must be of unit norm within QUATERNION_TOL (then it is normalised); a closed
        mechanism's q0 near its loops. ``second_order``: refuse a system whose dq/dt is not v
        (a stepper for y = (q, v), dq/dt = v)."""
        model = self.model
        q0 = check_state(model, "q", model.initial() if q0 is None else q0)
        v0 = check_state(model, "v", np.zeros(self.n_v) if v0 is None else v0)
        if self.loops is not None:
            self.loops.check_start(q0)
        if model.couplings:  # (the steps' right-hand side takes its state as given)
            check_coupled(model, "q", q0)
            check_coupled(model, "v", v0)
        for k, t in enumerate(model.joint_types):
            if t in QUATERNION_JOINTS:  # its quaternion, before any projection: the norm as given
                i = int(model.joint_qoff[k]) + (3 if t == FREE else 0)
                norm = math.sqrt(float(q0[i:i + 4] @ q0[i:i + 4]))
                if not abs(norm - 1.0) <= QUATERNION_TOL:
                    raise StateError(f"q0[{i}:{i + 4}], the quaternion (w, x, y, z) of joint "
                                     f"{model.joint_names[k]!r}, has norm {norm:.9g}: give a "
                                     "unit quaternion")
        if second_order and self.free:
            raise SettingsError(self.source, "integrator", "implicit", "steps systems whose "
                                "dq/dt is v; a free or ball joint's quaternion moves "
                                "otherwise: use ode45 or dop853")
        carry = work and not second_order and bool(self.work_forces)
        y0 = np.concatenate((q0, v0, [0.0] if carry else []))
        self.project(y0, record=False)
        return y0

    def reset(self) -> None:
        """Forget what earlier runs met (the projections' departures, the loops' change
        points)."""
        self.worst[:] = 0.0
        self._nearest[:] = math.inf, math.nan
        if self.loops is not None:
            self.loops.nearest_change_point()

    def after_step(self, t: float) -> None:
        """Keep how near the motion came to a loop's change point, up to the step ending at t."""
        if self.loops is not None:
            ratio = self.loops.nearest_change_point()
            if ratio < self._nearest[0]:
                self._nearest[:] = ratio, t

    @property
    def nearest_change_point(self) -> tuple[float, float]:
        """(the least s_min / s_max of the loops' J M^-1 J^T met, the time of its step)."""
        return self._nearest[0], self._nearest[1]


def _per_dof(source: str, name: str, value, n: int, meaning: str,
             per: str = "velocity coordinate") -> np.ndarray:
    """A number or one per ``per`` (velocity coordinate), each finite and >= 0, as (n,)."""
    if isinstance(value, bool) or not isinstance(value, NUMBERS) and np.ndim(value) != 1:
        raise SettingsError(source, name, value, f"must be a finite number >= 0: {meaning}")
    if isinstance(value, NUMBERS):
        if not (math.isfinite(value) and value >= 0):
            raise SettingsError(source, name, float(value), f"must be a finite number >= 0: "
                                f"{meaning}")
        return np.full(n, float(value))
    arr = _vector(source, name, value, n, per)
    if not (arr >= 0).all():
        raise SettingsError(source, name, value, f"every entry must be >= 0: {meaning}")
    return arr


def _vector(source: str, name: str, value, n: int, per: str = "velocity coordinate"
            ) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if isinstance(value, bool) or arr is None or arr.shape != (n,) or \
            not np.isfinite(arr).all():
        raise SettingsError(source, name, value, f"must be a number or {n} finite numbers, one "
                            f"per {per}")
    return arr


def _body_forces(source: str, model: Model, body_forces, gravcomp
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(bodies (m,), forces (m, 3), points (m, 3)) of the constant body forces: those given, then
    each compensated body's -gravcomp m g at its centre of mass, then the model's
    :attr:`~redysim.model.tree.Model.gravcomp_loads` (a fused body's parts of other fractions:
    -held mass g at each part's centre of mass) (SettingsError naming a bad one)."""
    names = list(model.body_names)
    body, force, point = [], [], []
    for i, item in enumerate(body_forces):
        try:
            name, f, x = item
        except (TypeError, ValueError):
            raise SettingsError(source, f"body_forces[{i}]", item, "must be (body name, force "
                                "(3,) [N], point (3,) [m] in the body's frame)") from None
        if name not in names:
            raise SettingsError(source, f"body_forces[{i}]", name, f"no such body; "
                                f"{model.name!r} has {', '.join(names[:12])}"
                                + (", ..." if len(names) > 12 else ""))
        body.append(names.index(name))
        force.append(_vector(source, f"body_forces[{i}].force", f, 3, "axis"))
        point.append(_vector(source, f"body_forces[{i}].point", x, 3, "axis"))
    factors = np.asarray(model.gravcomp, dtype=float)  # the model's own, then the setting's
    if gravcomp is not None:
        factors = factors + _gravcomp_factors(source, model, gravcomp)
    if factors.any():
        mass = np.asarray(model.mass, dtype=float)
        g = np.asarray(model.gravity, dtype=float)
        for k in np.flatnonzero((factors != 0.0) & (mass > 0.0)):
            body.append(int(k))
            force.append(-factors[k] * mass[k] * g)
            point.append(np.asarray(model.mass_com[k], dtype=float) / mass[k])
    g = np.asarray(model.gravity, dtype=float)
    for k, held, *x in model.gravcomp_loads:  # a fused body's parts, each at its own centre
        body.append(int(k))
        force.append(-held * g)
        point.append(np.array(x, dtype=float))
    return (np.array(body, dtype=np.int64), np.array(force, dtype=float).reshape(-1, 3),
            np.array(point, dtype=float).reshape(-1, 3))


def _gravcomp_factors(source: str, model: Model, gravcomp) -> np.ndarray:
    """The (nb,) fractions of a ``gravcomp`` setting (a number, one per body, or body name ->
    fraction), SettingsError naming a bad one."""
    names = list(model.body_names)
    if isinstance(gravcomp, dict):
        unknown = [b for b in gravcomp if b not in names]
        if unknown:
            raise SettingsError(source, "gravcomp", unknown[0], f"no such body; "
                                f"{model.name!r} has {', '.join(names[:12])}"
                                + (", ..." if len(names) > 12 else ""))
        factors = np.array([float(gravcomp.get(b, 0.0)) for b in names])
    else:
        factors = _per_dof(source, "gravcomp", gravcomp, model.n_bodies,
                           "the fraction of a body's weight held up", per="body")
    if not np.isfinite(factors).all():
        raise SettingsError(source, "gravcomp", gravcomp, "must be finite")
    if (np.abs(factors) > MAX_GRAVCOMP).any():
        raise SettingsError(source, "gravcomp", gravcomp, f"must be <= {MAX_GRAVCOMP:g}: the "
                            "fraction of a body's weight held up (1: all of it); a larger one "
                            "is a unit slip")
    return factors


def passive_forces(model: Model, q, v) -> np.ndarray:
    """The model's own passive generalized forces at (q, v) (n_v,): -damping v - stiffness (q -
    spring_ref) + J^T of each body's held-up weight gravcomp m (-g) at its centre of mass
    (:attr:`Model.damping`, ...; MuJoCo's ``qfrc_passive`` without fluid forces), from the very
    function a run's steps call (:class:`System`), so in the same bits. Zeros for a model without
    them. Raises StateError for a bad state (naming it)."""
    door.require_model(model, "passive_forces")
    q, v = check_state(model, "q", q), check_state(model, "v", v)
    if not model.has_passive:
        return np.zeros(model.n_v)
    system = System(model, source="passive_forces")
    out = system.forces(0.0, q, v)
    return np.zeros(model.n_v) if out is None else out


def _tip_force(source: str, model: Model, tip_force):
    if tip_force is None:
        return None
    if model.chain_layout is not None:
        raise SettingsError(source, "tip_force", tip_force, f"acts at a chain's tip; "
                            f"{model.name!r} is a tree (no single tip)")
    try:
        return check_force(tip_force)
    except StateError as exc:
        raise SettingsError(source, "tip_force", tip_force, str(exc)) from None
