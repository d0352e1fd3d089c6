"""The public dynamics functions: checked at the door, then handed to the kernels.

Every function takes a :class:`~redysim.model.tree.Chain` or a :class:`~redysim.model.tree.Model` (a
kinematic tree: a chain is one) and numpy vectors in SI units and returns numpy arrays: q of length
``n_q``, velocities, accelerations and forces of length ``n_v`` (both ``n_dof`` for a chain; a free
joint has 7 and 6). The scratch space comes from the model itself: called without ``ws=``, a
function uses the calling thread's workspace of the model (made on its first call, then reused:
:func:`redysim.algorithms.workspace.model_workspace`), so the default call is the fast one, safe
from any number of threads. ``ws=`` hands a :class:`~redysim.algorithms.workspace.Workspace` of your
own instead (the same results, bit for bit).
"""

from __future__ import annotations

import math
import reprlib
import time
from typing import Literal, NamedTuple, overload

import numpy as np
from numpy import ndarray

from redysim._jit import JIT_ENABLED
from redysim.algorithms._kernels import batch as _batch
from redysim.algorithms._kernels import couplings as _couplings
from redysim.algorithms._kernels import lean as _lean
from redysim.algorithms._kernels import tiles as _tiles
from redysim.algorithms._kernels.couplings import COUPLED as _COUPLED
from redysim.algorithms._kernels.elimination import ge_n, rge_n
from redysim.algorithms._kernels.energy import energy as _energy
from redysim.algorithms._kernels.entry import DH as _DH
from redysim.algorithms._kernels.entry import DH_INVERSE as _DH_INVERSE
from redysim.algorithms._kernels.entry import PLANAR as _PLANAR
from redysim.algorithms._kernels.entry import RGE_A as _RGE_A
from redysim.algorithms._kernels.entry import SIZE_MISMATCH
from redysim.algorithms._kernels.gim import gim_composite
from redysim.algorithms._kernels.inverse_dynamics import rnea_backward
from redysim.algorithms._kernels.kinematics import kinematics as _kinematics
from redysim.algorithms._kernels.momentum import momentum_gradient
from redysim.algorithms._kernels.rge_a import rge_a_backward
from redysim.algorithms._kernels.udu import udu_assemble
from redysim.algorithms.dh_form import dh_problem
from redysim.algorithms.methods import ELIMINATIONS, METHODS, PAPER_NAMES  # noqa: F401  (re-exported)
from redysim.algorithms.threads import (  # noqa: F401  (default_threads: re-exported)
    chunk_edges,
    default_threads,
    plan,
    run_blocks,
)
from redysim.algorithms.vectors import cross
from redysim.algorithms.workspace import Workspace, model_workspace
from redysim.errors import CaseError, FieldError, StateError
from redysim.model import door
from redysim.model.parts import NUMERIC_KINDS
from redysim.model.tree import QUATERNION_JOINTS, Model

FLOAT64, FLOAT64_STRIDES = np.dtype(np.float64), (8,)


def _plain_vector(x, n: int) -> bool:
    """True for a contiguous, aligned, native float64 ndarray of shape (n,): what the kernels
    take as is (:func:`redysim.model.door.plain_vector`)."""
    return door.plain_vector(x, n)


def _owner(model: Model) -> str:
    return f"{type(model).__name__.lower()} {model.name!r}"


@overload
def check_state(model: Model, name: str, x, *, optional: Literal[False] = False,
                finite: bool = True) -> np.ndarray: ...


@overload
def check_state(model: Model, name: str, x, *, optional: bool,
                finite: bool = True) -> np.ndarray | None: ...


def check_state(model: Model, name: str, x, *, optional: bool = False,
                finite: bool = True) -> np.ndarray | None:
    """Return ``x`` as a float vector of length n (``n_q`` for the configuration ``q``, else
    ``n_v``), or raise StateError naming it (the door: :func:`redysim.model.door.vector`).

    ``finite=False`` skips the NaN/Inf scan (the hot path of :func:`forward_dynamics` checks its
    result instead and only then looks for the offending input).
    """
    n = model.n_q if name == "q" else model.n_v
    if x is None:
        if optional:
            return None
        raise StateError(f"{name} is required (a vector of {n} values)")
    if door.plain_vector(x, n):  # the hot path: as given
        if finite:
            require_finite(name, x)
        return x
    what = "configuration coordinates" if name == "q" else "DOF"
    hint = ""
    if name != "q" and _is_batch(x):
        hint = f" (q is one state; for a batch of states give q as (B, {model.n_q}) too)"
    return door.vector(name, x, n, owner=_owner(model), what=what, finite=finite, hint=hint)


def check_out(model: Model, out) -> np.ndarray:
    """``out`` as given if the kernels can write an (n,) float vector into it, else StateError
    (:func:`redysim.model.door.out_vector`).

    The kernels index without bounds checks: a short or strided ``out`` would be written past
    its end, so it is refused here, never converted (a copy would not reach the caller).
    """
    return door.out_vector(out, model.n_v, owner=repr(model.name))


require_finite = door.require_finite


def overflow_error(what: str, **inputs) -> StateError:
    """The error for a non-finite result of finite inputs: the recursion overflowed."""
    sizes = ", ".join(f"max |{k}| = {np.abs(v).max():.3g}" for k, v in inputs.items()
                      if v is not None)
    names = ", ".join(k for k, v in inputs.items() if v is not None)
    return StateError(f"{what} is not finite for finite {names} ({sizes}): overflow?")


def _ws(model: Model, ws: Workspace | None, where: str = "dynamics") -> Workspace:
    """The workspace of a call: ``ws``, checked, or the model's own for this thread. The door's
    model check happens here off the hot path: only a Model has a thread's workspace to find
    (forward_dynamics's first step), and a Workspace is made for a Model only."""
    if ws is None:  # the model's own workspace for this thread (model_workspace)
        try:
            return model._thread_workspaces.ws
        except AttributeError:
            door.require_model(model, where)
            return model_workspace(model)
    if getattr(ws, "model", None) is not model:  # one attribute read on the hot path
        door.require_model(model, where)
        if not isinstance(ws, Workspace):
            raise FieldError("dynamics", "ws", type(ws).__name__, "must be a redysim.Workspace")
        if repr(ws.model) == repr(model):  # the same description: another object
            raise FieldError("dynamics", "ws", repr(ws.model), "was made for another Model "
                             "object with the same description (a file loaded again gives a "
                             "new model; a Workspace serves the very model it was made for): "
                             "make one with Workspace(model)")
        raise FieldError("dynamics", "ws", repr(ws.model), f"was made for another chain than "
                         f"{model!r}; make one with Workspace(model)")
    return ws


def first_bad_pivot(pivots: np.ndarray, *, from_base: bool, positive: bool) -> int | None:
    """The first pivot, in elimination order (from index 0 with ``from_base``, else from the
    last), that cannot be divided by: 0, not finite, so small that 1/p overflows, or (with
    ``positive``, for a symmetric positive definite GIM) not > 0. None when there is none."""
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        bad = ~np.isfinite(pivots) | ~np.isfinite(1.0 / pivots)
        if positive:
            bad |= ~(pivots > 0)
    idx = np.flatnonzero(bad)
    return None if not idx.size else int(idx.min() if from_base else idx.max())


def _run_kinematics(model, ws, q, v, qdd, base_accel):
    _kinematics(ws.tree, q, v, qdd, base_accel, ws.s)


def _phi(model, ws, q, v, tau):
    """phi = tau - (C v + gravity terms) into ws.phi (kinematics with qdd = 0, base at -g)."""
    c = model
    _run_kinematics(c, ws, q, v, ws.zeros, ws.base_accel)
    rnea_backward(ws.tree, ws.s, ws.zeros, ws.phi)
    ws.phi *= -1.0
    if tau is not None:
        ws.phi += tau
    return ws.phi


# inverse_dynamics calls of at most this many DOF go to the evaluator's lean entry
# (redysim.evaluator), which holds the GIL: its checked path spends a fixed time in Python
# (holding the GIL) calling the passes, and up to about this size the lean entry holds it for
# less than that in all. (forward_dynamics keeps its own entry: the lean one saved a fraction of
# a microsecond a call but doubled a fresh install's first compile. The figures:
# docs/notes/2026-11-evaluator-and-ladder.md)
LEAN_INVERSE_MAX_DOF = 500
COUPLING_TOL = _couplings.COUPLING_TOL  # |q_f - (m q_l + offset)| allowed, relative to 1 + |q_f|


def given_tolerance(x) -> float:
    """The couplings' tolerance for a vector given as ``x``: COUPLING_TOL, or, for a vector of
    a narrower float (float32, float16: converted at the door), 8 units of its own roundoff."""
    try:
        dtype = np.asarray(x).dtype
    except (TypeError, ValueError):
        return COUPLING_TOL
    return max(COUPLING_TOL, 8.0 * float(np.finfo(dtype).eps)) if dtype.kind == "f" else \
        COUPLING_TOL


def check_coupled(model: Model, name: str, x: np.ndarray, tol: float = COUPLING_TOL) -> None:
    """Refuse a state off the model's couplings (StateError naming the joints and values): a
    follower's ``q`` must be m q_l + offset, its ``v`` (or ``qdd``) m times its leader's, to
    ``tol`` relative to 1 + |q_f| (:func:`given_tolerance`: a float32 vector's is its own)."""
    i = 0 if name == "q" else 2
    idx = model.coupling_index
    f, ld, m = idx[i], idx[i + 1], idx[4]
    want = m * x[ld] + (idx[5] if name == "q" else 0.0)
    bad = np.abs(x[f] - want) > tol * (1.0 + np.abs(x[f]))
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        c = model.couplings[k]
        raise StateError(f"{name}[{int(f[k])}] = {x[f[k]]:.17g}, joint {c.follower!r}, follows "
                         f"joint {c.leader!r} ({name}[{int(ld[k])}] = {x[ld[k]]:.17g}) with "
                         f"multiplier {c.multiplier:g}" + (f" and offset {c.offset:g}"
                                                           if name == "q" else "")
                         + f": it must be {want[k]:.17g} (model.couple(q, v) sets the "
                         "followers from their leaders)")


def _coupled_forward(model: Model, q, v, tau, method: str, planar, out,
                     ws: Workspace | None = None,
                     tols: tuple[float, float] | None = None) -> np.ndarray:
    """qdd of a coupled model (:meth:`Model.with_couplings`), its state checked: with RGE-A on a
    spatial tree, in RGE-A's recursion on the workspace (``ws``, or the thread's:
    :func:`redysim.algorithms._kernels.couplings.coupled_qdd`); else by Featherstone's method on
    the tree: qdd0 the tree's, X = M^-1 J^T by the tree's forward dynamics with no gravity and no
    velocity (one call per coupling; J's rows e_f - m e_l), then (J X) lam = -J qdd0 and qdd =
    qdd0 + X lam, which holds every follower's qdd at m times its leader's (J qdd = 0: the
    couplings are linear, so Jdot v = 0)."""
    tol_q, tol_v = tols or (given_tolerance(q), given_tolerance(v))  # (a batch's: as given)
    q = check_state(model, "q", q)
    v = check_state(model, "v", v)
    tau = check_state(model, "tau", tau, optional=True)
    check_coupled(model, "q", q, tol_q)
    check_coupled(model, "v", v, tol_v)
    ws = _ws(model, ws)
    if method == "rge-a" and not planar and ws.coupled:
        # in compiled code, as a simulation's right-hand side; where the result is not finite,
        # the calls below say why
        from redysim.algorithms._kernels.system import coupled_qdd

        res = check_out(model, out)  # (compiled code writes it: the door's checks first)
        # writable arrays: a read-only one is another numba type (one compile more)
        a, b, t = (x if x.flags.writeable else x.copy()
                   for x in (q, v, ws.zeros if tau is None else tau))
        if coupled_qdd(ws.kernel_f, ws.kernel_i, ws.scratch, a, b, t, res) == 0.0:
            return res
    tree, free = model.tree, model.free_tree
    qdd = forward_dynamics(tree, q, v, tau, method, planar=planar)
    _, _, fv, lv, m, _ = model.coupling_index
    n, k = model.n_v, fv.shape[0]
    J = np.zeros((k, n))
    J[np.arange(k), fv] = 1.0
    np.subtract.at(J, (np.arange(k), lv), m)
    zeros = np.zeros(n)
    X = np.column_stack([forward_dynamics(free, q, zeros, row, method, planar=planar)
                         for row in J])
    lam = np.linalg.solve(J @ X, -(J @ qdd))
    qdd = qdd + X @ lam
    qdd[fv] = m * qdd[lv]  # exactly on the couplings (the solve leaves rounding)
    if not np.isfinite(qdd).all():
        raise overflow_error("qdd", q=q, v=v, tau=tau)
    if out is None:
        return qdd
    out = check_out(model, out)
    out[:] = qdd
    return out


def use_dh_kernels(model: Model, has_form: bool, dh, planar: bool) -> bool:
    """Whether forward or inverse dynamics run the DH kernels: ``dh`` None (when the model has
    the DH form, ``has_form``: its workspace's ``dh``, and the planar kernel does not run), True
    (the form required) or False."""
    if dh is None or dh is False:
        return dh is None and not planar and has_form
    if dh is not True:
        raise FieldError("dynamics", "dh", dh, "must be None, True or False")
    if planar or not has_form:
        why = "the planar kernel runs it" if planar else dh_problem(model)
        raise ValueError(f"dh=True but model {model.name!r} is not a robot in DH form: {why}")
    return True


def closed_error(model: Model, what: str) -> CaseError:
    """The refusal of ``what`` on a model with cut joints, whose tree's answer would ignore
    them silently."""
    return CaseError(model.name, "cuts", [c.name for c in model.cuts],
                     f"{what} of a model with cut joints: the tree's recursions ignore the loops; "
                     "close them with redysim.ClosedLoops(model), or open the model with "
                     "model.with_cuts(())")


# --------------------------------------------------------------------------- inverse dynamics
def inverse_dynamics(model: Model, q, v, qdd, *, ws: Workspace | None = None,
                     threads: int | None = None, dh: bool | None = None) -> np.ndarray:
    """tau = I(q) qdd + C(q, v) v + gravity terms, by the recursive Newton-Euler pass (Eq. 9).

    A batch: q (B, n_q), v and qdd (B, n_v) give tau (B, n_v), each row the single call's, the
    rows on threads (``threads``, as for :func:`forward_dynamics`).

    A coupled model (:meth:`Model.with_couplings`): q, v and qdd must keep the couplings, and
    tau is the tree's (each joint's torque for that motion, with no coupling force), which
    :func:`forward_dynamics` maps back to qdd.

    dh: a robot in Denavit-Hartenberg form (:mod:`redysim.algorithms.dh_form`) runs the
    DH-specialised Newton-Euler pass (:mod:`redysim.algorithms._kernels.dh`; the same torques
    to rounding) unless ``dh=False``; ``dh=True`` requires the form (ValueError saying why not).

    Contiguous float64 vectors of a model of at most LEAN_INVERSE_MAX_DOF DOF go to one compiled
    function as they are (:func:`redysim.evaluator`'s inverse entry, the same passes and bits);
    anything else is checked and converted first.
    """
    door.require_model(model, "inverse_dynamics")
    if model.cuts:
        raise closed_error(model, "inverse_dynamics")
    ws = _ws(model, ws)
    use_dh = ws.dh if dh is None else use_dh_kernels(model, ws.dh, dh, False)
    if _is_batch(q):
        if model.couplings:
            return np.array([inverse_dynamics(model, *row, ws=ws, dh=dh)
                             for row in zip(*(check_batch(model, name, x, None)
                                              for name, x in (("q", q), ("v", v),
                                                              ("qdd", qdd))), strict=True)])
        return _inverse_batch(model, ws, q, v, qdd, threads, use_dh)
    if not model.couplings and model.n_v <= LEAN_INVERSE_MAX_DOF and _lean.NUMPY_LAYOUT_OK \
            and JIT_ENABLED:
        entry = (_lean.INVERSE_DH if use_dh else _lean.INVERSE_CHAIN if ws.tree.serial
                 else _lean.INVERSE_TREE).call
        try:  # the hot path, the evaluator's entry: it checks types, lengths, strides, result
            return entry(q, v, qdd, np.empty(model.n_v), ws.kernel_f, ws.kernel_i, ws.scratch)
        except (TypeError, _lean.Refused):  # not contiguous float64, a length, not finite:
            pass  # converted and checked below, which names what is wrong
    q = check_state(model, "q", q)
    v = check_state(model, "v", v)
    qdd = check_state(model, "qdd", qdd)
    if model.couplings:  # the tree's torques: the coupled motion's, with no coupling force
        for name, x in (("q", q), ("v", v), ("qdd", qdd)):
            check_coupled(model, name, x)
    c = model
    tau = np.empty(c.n_v)
    if use_dh:
        _DH_INVERSE.compiled(ws.kernel_f, ws.kernel_i, q, v, qdd, ws.scratch, tau)
    else:
        _run_kinematics(c, ws, q, v, qdd, ws.base_accel)
        rnea_backward(ws.tree, ws.s, qdd, tau)
    if not np.isfinite(tau).all():
        raise overflow_error("tau", q=q, v=v, qdd=qdd)
    return tau


def phi(model: Model, q, v, tau=None, *, ws: Workspace | None = None) -> np.ndarray:
    """phi = tau - C(q, v) v - gravity terms (Eq. 12), the right-hand side of I qdd = phi."""
    door.require_model(model, "phi")
    q = check_state(model, "q", q)
    v = check_state(model, "v", v)
    tau = check_state(model, "tau", tau, optional=True)
    out = _phi(model, _ws(model, ws), q, v, tau).copy()
    if not np.isfinite(out).all():
        raise overflow_error("phi", q=q, v=v, tau=tau)
    return out


# --------------------------------------------------------------------------- forward dynamics
def forward_dynamics(model: Model, q, v, tau=None, method: str = "rge-a", *,
                     planar: bool | None = None, ws: Workspace | None = None,
                     out: np.ndarray | None = None, threads: int | None = None,
                     simd: bool = True, dh: bool | None = None) -> np.ndarray:
    """qdd from I(q) qdd = phi(q, v, tau).

    method:
        ``"rge-a"``: O(n) Reverse Gaussian Elimination done analytically (Table A.1), the default;
        ``"ge-n"``:  the GIM by composite masses, then Gaussian elimination, O(n^3);
        ``"rge-n"``: the GIM, then reverse Gaussian elimination, O(n^3) (section 5.2).
    planar: for ``"rge-a"``, use the planar specialisation (default: when ``chain.is_planar``,
        a Chain's property: a Model always takes the spatial recursion);
        ``False`` forces the spatial recursion.
    dh: for ``"rge-a"``, a robot in Denavit-Hartenberg form (:mod:`redysim.algorithms.dh_form`:
        a serial chain of R and P joints along z, each placed by Rx Tx Rz Tz) runs the
        DH-specialised articulated-body recursion (:mod:`redysim.algorithms._kernels.dh`; the
        same qdd to rounding, fewer operations) unless ``dh=False``; ``dh=True`` requires the
        form (ValueError saying why not). Batches run it too with ``simd=False``; in SIMD tiles
        they run the general recursion.
    tau: joint forces (default zero). ``out``: an (n,) array to write qdd into.

    A batch: q (B, n_q) and v (B, n_v) give qdd (B, n_v), row i the single call's for row i; tau (B,
    n_v), or (n_v,) for every state; ``out`` (B, n_v). RGE-A only. The rows run in compiled code on
    up to ``threads`` threads (default :func:`default_threads`: every core this process may use, or
    ``REDYSIM_THREADS``), in chunks of up to 8,000 DOF-states (a smaller batch runs on the calling
    thread): the caller works through the chunks, and helper threads take chunks too when they get a
    core, each in arrays of its own; a chunk a helper is late with the caller runs itself, and each
    workspace measures, per kind of batch, whether helpers pay (else it pauses them), so that a busy
    machine costs a batch no more than a few percent over ``threads=1`` (docs/design.md,
    "Threads under load"). Each row's bits do not depend on the threads. With ``simd`` (the
    default), a system in the spatial recursion (a chain, or any tree: robots, free joints) runs its
    states 16 at a time in SIMD lanes (:mod:`redysim.algorithms._kernels.tiles`, several states
    in a single call's time on one core: docs/notes/2026-11-batches-and-tiles.md): row i then
    equals the single call to rounding (``tests/test_tiles.py``), not bit for bit; ``simd=False``
    gives the single calls' bits. A batch's last rows, when they fill less than half a tile,
    systems over 10,000 DOF, planar chains (their own kernel) and any batch with |q| > 1e5 run row
    by row.

    Fastest with contiguous float64 vectors and ``out`` (an integrator's loop), with or without
    ``ws`` (without, the model's own workspace for the calling thread: the same speed and bits):
    these go to the compiled entry point as they are, which checks their types and sizes
    itself. Anything else is checked and converted first: lists at once, other arrays (float32,
    strided) after numba refuses their types, a slower path.

    A model with cut joints is refused (:class:`redysim.ClosedLoops` closes them). A coupled
    model (:meth:`Model.with_couplings`: mimic joints) gives its coupled motion: with RGE-A on a
    spatial tree, the couplings in RGE-A's recursion, in compiled code (the tree's call, a sweep
    of each coupling's paths to the root and one more forward pass: O(n); batches row by row, no
    SIMD tiles); else by Featherstone's method on the tree in Python (1 + len(couplings) tree
    calls). q and v must keep its couplings (StateError otherwise: ``model.couple(q, v)`` sets
    them).
    """
    ws = _ws(model, ws, "forward_dynamics")
    if method != "rge-a" and method not in METHODS:
        raise FieldError("forward_dynamics", "method", method,
                         f"unknown; choose one of {', '.join(METHODS)}")
    if model.cuts or model.couplings:
        if model.cuts:
            raise closed_error(model, "forward_dynamics")
        if method == "rge-a" and not planar and ws.coupled:
            # the hot path, as below: RGE-A and the couplings in its recursion, one compiled call
            t = ws.zeros if tau is None else tau
            if type(q) is ndarray and type(v) is ndarray and type(t) is ndarray:
                if q.ndim == 2:
                    return _coupled_batch(model, ws, q, v, tau, out, threads)
                qdd = np.empty(model.n_v) if out is None else out
                if type(qdd) is ndarray:
                    try:
                        flag = _COUPLED.compiled(ws.kernel_f, ws.kernel_i, q, v, t, ws.scratch,
                                                 qdd)
                    except TypeError:  # not all contiguous float64: the checked path
                        flag = SIZE_MISMATCH
                    if flag == 0.0:
                        return qdd
        if _is_batch(q):
            Q = check_batch(model, "q", q, None)
            V = check_batch(model, "v", v, Q.shape[0])
            T = None
            if tau is not None:  # (n_v,) for every state, or a row each
                T = np.asarray(tau, dtype=float)
                if T.shape == (model.n_v,):
                    T = np.broadcast_to(T, (Q.shape[0], model.n_v))
                T = check_batch(model, "tau", T, Q.shape[0])
            res = check_batch_out(model, out, Q.shape[0])
            tols = (given_tolerance(q), given_tolerance(v))
            for i in range(Q.shape[0]):
                try:
                    res[i] = _coupled_forward(model, Q[i], V[i], None if T is None else T[i],
                                              method, planar, None, ws, tols=tols)
                except StateError as exc:
                    raise StateError(f"state {i} of the batch (row {i} of q and v): {exc}") \
                        from None
            return res
        return _coupled_forward(model, q, v, tau, method, planar, out, ws)
    is_planar = model.is_planar
    if planar is None:
        planar = is_planar
    elif planar and not is_planar:
        raise FieldError("forward_dynamics", "planar", True, f"chain {model.name!r} is not "
                         "planar (every joint must be a single revolute about its frame's z "
                         "axis)")
    use_dh = (ws.dh and not planar) if dh is None else use_dh_kernels(model, ws.dh, dh, planar)
    if method == "rge-a":
        entry = (_PLANAR if planar else _DH if use_dh else _RGE_A).compiled
        qdd = np.empty(model.n_v) if out is None else out
        t = ws.zeros if tau is None else tau
        if type(q) is ndarray and type(v) is ndarray and type(t) is ndarray \
                and type(qdd) is ndarray:
            if q.ndim == 2:  # a batch (before the entry: its TypeError is slow)
                return _forward_batch(model, ws, planar, q, v, tau, out, threads, simd, use_dh)
            try:  # the hot path: no conversion, the entry checks the sizes
                flag = entry(ws.kernel_f, ws.kernel_i, q, v, t, ws.scratch, qdd)
            except TypeError:  # not all contiguous float64 (qdd writeable): check, convert
                flag = SIZE_MISMATCH
            if flag == 0.0:
                return qdd
            if flag != SIZE_MISMATCH:  # NaN: some qdd is NaN or +-inf
                raise _nonfinite_qdd(model, ws, planar, q, v, tau, use_dh=use_dh)
    if _is_batch(q):
        if method != "rge-a":
            raise FieldError("forward_dynamics", "method", method, "with a batch of states: "
                             "batches run 'rge-a' only")
        return _forward_batch(model, ws, planar, q, v, tau, out, threads, simd, use_dh)
    q = check_state(model, "q", q, finite=False)
    v = check_state(model, "v", v, finite=False)
    tau = check_state(model, "tau", tau, optional=True, finite=False)
    out = check_out(model, out)
    c = model
    if method == "rge-a":
        nonfinite = entry(ws.kernel_f, ws.kernel_i, q, v, ws.zeros if tau is None else tau,
                          ws.scratch, out)
    else:
        rhs = _phi(c, ws, q, v, tau).copy()
        A = np.empty((c.n_v, c.n_v))
        gim_composite(ws.tree, ws.s, A)
        mult = np.zeros_like(A)
        (ge_n if method == "ge-n" else rge_n)(A, rhs, mult, out)
        nonfinite = float(np.sum(out * 0.0))
    if nonfinite != 0.0:
        raise _nonfinite_qdd(model, ws, method == "rge-a" and planar, q, v, tau,
                             gim=None if method == "rge-a" else A, first=method == "ge-n",
                             use_dh=method == "rge-a" and use_dh)
    return out


# --------------------------------------------------------------------------- batches
# A batch's rows run on the calling thread and helper threads (redysim.algorithms.threads, whose
# module docstring is the contract): _forward_tiled and _run_rows say what a chunk is and how a
# helper's chunk reaches the outputs.


def _is_batch(x) -> bool:
    """True for a 2-D array (or nested list) of states; False for anything else, ragged lists
    included (the single call's checks then say what is wrong)."""
    try:
        return np.ndim(x) == 2
    except ValueError:
        return False


def check_batch(model: Model, name: str, x, rows: int | None, *,
                label: str | None = None) -> np.ndarray:
    """``x`` as a C-contiguous float64 (B, n) array (n = ``n_q`` for ``q``, else ``n_v``) with
    ``rows`` rows when given (the rows of the batch's ``q``), or StateError naming it (as
    ``label``, default ``name``) and saying what a batch needs."""
    n = model.n_q if name == "q" else model.n_v
    label = label or name
    try:
        arr = np.asarray(x)
    except (TypeError, ValueError) as exc:
        raise StateError(f"{label} = {reprlib.repr(x)}: not a numeric array ({exc})") from None
    if arr.dtype.kind not in NUMERIC_KINDS:
        raise StateError(f"{label} = {reprlib.repr(x)}: not a numeric array (its entries are "
                         f"{arr.dtype}; need int or float)")
    if arr.ndim == 2 and arr.shape[1] == n and (rows is None or arr.shape[0] == rows):
        return door.native(arr)
    what = "configuration coordinates" if name == "q" else "DOF"
    has = f"{type(model).__name__.lower()} {model.name!r} has {n} {what}"
    if rows is None:  # the batch's own rows: q
        raise StateError(f"{label} has shape {arr.shape}; {has}, so {label} must have shape "
                         f"({n},) for one state, or (B, {n}) for a batch, one state a row")
    raise StateError(f"{label} has shape {arr.shape}; q is a batch of {rows} states, so {label} "
                     f"must have shape ({rows}, {n}), one row per row of q ({has})"
                     + (f"; for the same {label} in every row, np.tile({label}, ({rows}, 1))"
                        if arr.shape == (n,) else ""))


def _run_rows(Q, n: int, threads: int | None, ws: Workspace, kernel, out, *inputs) -> int:
    """kernel(f, i, Q, *inputs, scratch, out, first, last) over the rows of Q in chunks of up to
    CHUNK_WORK DOF-states (:mod:`redysim.algorithms.threads`), on the threads its plan gives:
    the caller in ``ws``'s scratch, into ``out``; a helper in its own scratch, into an array of
    its own that the caller copies into ``out`` (inputs: arrays of B rows, or of one row for
    every state). The first failing row (the lowest of the chunks') or -1."""
    rows = Q.shape[0]
    edges = chunk_edges(rows, rows * n)
    count, speed = plan(ws.batch_speed, (kernel, len(edges)), threads, len(edges) - 1)
    f, i = ws.kernel_f, ws.kernel_i
    t0 = time.perf_counter()
    if count == 1:
        bad = kernel(f, i, Q, *inputs, ws.scratch, out, 0, rows)
        if speed is not None:
            speed.record(False, (time.perf_counter() - t0) / (rows * n))
        return bad

    def call(first, last, own):
        if own is None:
            return kernel(f, i, Q, *inputs, ws.scratch, out, first, last)
        mine = np.empty((last - first, out.shape[1]))
        bad = kernel(f, i, Q[first:last], *(x if x.shape[0] == 1 else x[first:last]
                                            for x in inputs),
                     own.get(ws.scratch), mine, 0, last - first)
        return (bad if bad < 0 else first + bad), mine

    def commit(first, last, mine):
        out[first:last] = mine

    failed = [r for r in run_blocks(rows, threads, call, count, edges=edges, commit=commit)
              if r >= 0]
    if speed is not None:
        speed.record(True, (time.perf_counter() - t0) / (rows * n))
    return min(failed) if failed else -1


TILE_MIN_ROWS = _tiles.LANES // 2  # a batch's last tile runs as a tile from this many rows
TILE_MAX_Q = 1e5  # |q| up to which the tiles' cos and sin reduce angles to within 1 ulp
TILE_MAX_DOF = 10_000  # beyond: rows (a thread's tile arrays are ~3.5 kB a DOF, 35 MB here;
# and large tiles are bound by memory: docs/notes/2026-11-batches-and-tiles.md)


def _forward_tiled(ws, Q, V, TAU, out, threads) -> int:
    """RGE-A over the batch's rows in SIMD tiles, the rows after the last tile one by one; the
    first row whose qdd is not finite, or -1. With several threads: chunks of whole tiles, from
    row 0 (the rows that run in tiles, and in which tile, do not depend on the threads), and the
    rows after them as one more chunk (:func:`run_blocks`, as :func:`_run_rows`)."""
    B, n, lanes = Q.shape[0], Q.shape[1], _tiles.LANES
    full, tail = divmod(B, lanes)
    tiles = full + (tail >= TILE_MIN_ROWS)
    split = min(B, tiles * lanes)
    edges = [min(e * lanes, split) for e in chunk_edges(tiles, B * n)]  # whole tiles
    edges += [B] if split < B and len(edges) > 2 else []  # (one chunk: one thread, as below)
    count, speed = plan(ws.batch_speed, ("tiles", len(edges)), threads, len(edges) - 1)
    f, i = ws.kernel_f, ws.kernel_i
    forward_tiles = _tiles.forward_tree_tiles if ws.tiles_tree else _tiles.forward_tiles
    t0 = time.perf_counter()
    if count == 1:
        bad = forward_tiles(f, i, Q, V, TAU, out, 0, split, ws.tile_buffer(1)[0])
        if bad < 0 and split < B:
            bad = _batch.forward_rows(f, i, Q, V, TAU, ws.scratch, out, split, B)
        if speed is not None:
            speed.record(False, (time.perf_counter() - t0) / (B * n))
        return bad

    def call(first, last, own):
        if own is None:
            if first >= split:  # the rows after the last tile
                return _batch.forward_rows(f, i, Q, V, TAU, ws.scratch, out, first, last)
            return forward_tiles(f, i, Q, V, TAU, out, first, last, ws.tile_buffer(1)[0])
        mine = np.empty((last - first, n))
        q, v = Q[first:last], V[first:last]
        tau = TAU if TAU.shape[0] == 1 else TAU[first:last]
        if first >= split:
            bad = _batch.forward_rows(f, i, q, v, tau, own.get(ws.scratch), mine, 0,
                                      last - first)
        else:  # (first is a multiple of 16: the same tiles as on the caller)
            bad = forward_tiles(f, i, q, v, tau, mine, 0, last - first,
                                own.get(ws.tile_buffer(1)[0]))
        return (bad if bad < 0 else first + bad), mine

    def commit(first, last, mine):
        out[first:last] = mine

    failed = [r for r in run_blocks(B, threads, call, count, edges=edges, commit=commit)
              if r >= 0]
    if speed is not None:
        speed.record(True, (time.perf_counter() - t0) / (B * n))
    return min(failed) if failed else -1


def check_batch_out(model: Model, out, rows: int) -> np.ndarray:
    """A batch's ``out``: a new (rows, n_v) array, or ``out`` as given if compiled code can
    write the batch into it (never converted: a copy would not reach the caller), else
    StateError saying what it must be (coupled or not, one refusal)."""
    if out is None:
        return np.empty((rows, model.n_v))
    if not (type(out) is ndarray and out.shape == (rows, model.n_v) and out.dtype is FLOAT64
            and out.flags.c_contiguous and out.flags.aligned and out.flags.writeable):
        what = (f"shape {out.shape}, dtype {out.dtype}" if isinstance(out, np.ndarray)
                else f"a {type(out).__name__}")
        raise StateError(f"out ({what}) must be a writeable, C-contiguous float64 array of "
                         f"shape ({rows}, {model.n_v}): one row of qdd per row of q")
    return out


def _forward_batch(model, ws, planar, q, v, tau, out, threads, simd=True,
                   use_dh=False) -> np.ndarray:
    Q = check_batch(model, "q", q, None)
    B = Q.shape[0]
    V = check_batch(model, "v", v, B)
    if tau is None:
        TAU = ws.zeros.reshape(1, -1)
    elif np.ndim(tau) == 1:
        TAU = check_state(model, "tau", tau, finite=False).reshape(1, -1)
    else:
        TAU = check_batch(model, "tau", tau, B)
    out = check_batch_out(model, out, B)
    if not isinstance(simd, bool | np.bool_):
        raise FieldError("forward_dynamics", "simd", simd, "must be True or False")
    if simd and not planar and ws.tiles_ok and B >= TILE_MIN_ROWS \
            and model.n_v <= TILE_MAX_DOF \
            and np.abs(Q).max() <= TILE_MAX_Q:  # (NaN compares False: the rows say why)
        bad = _forward_tiled(ws, Q, V, TAU, out, threads)
    else:
        rows = _batch.planar_rows if planar else _batch.dh_rows if use_dh else _batch.forward_rows
        bad = _run_rows(Q, model.n_v, threads, ws, rows, out, V, TAU)
    if bad >= 0:  # the single call of that row says why
        t = TAU[0] if TAU.shape[0] == 1 else TAU[bad]
        try:
            forward_dynamics(model, Q[bad], V[bad], t, planar=planar, ws=ws, dh=use_dh)
        except StateError as exc:
            raise StateError(f"state {bad} of the batch (row {bad} of q and v): {exc}") from None
        raise StateError(f"state {bad} of the batch: qdd not finite")  # (not reached)
    return out


def _coupled_batch(model, ws, q, v, tau, out, threads) -> np.ndarray:
    """A coupled model's batch (RGE-A on a spatial tree): the rows through the coupled entry
    (:func:`redysim.algorithms._kernels.couplings.coupled_rows`, no SIMD tiles) on the threads
    :func:`_run_rows` plans; the first row that fails (off the couplings, not finite) is then
    run alone, which says why."""
    Q = check_batch(model, "q", q, None)
    B = Q.shape[0]
    V = check_batch(model, "v", v, B)
    if tau is None:
        TAU = ws.zeros.reshape(1, -1)
    else:  # (n_v,) for every state, or a row each
        T = np.asarray(tau, dtype=float)
        TAU = (check_state(model, "tau", T).reshape(1, -1) if T.shape == (model.n_v,)
               else check_batch(model, "tau", T, B))
    out = check_batch_out(model, out, B)
    tol_q, tol_v = given_tolerance(q), given_tolerance(v)
    if max(tol_q, tol_v) > COUPLING_TOL:  # a narrower float: each row held to its own
        # roundoff, as the single call holds it (the compiled rows check at float64's)
        for i in range(B):
            t = TAU[0] if TAU.shape[0] == 1 else TAU[i]
            try:
                out[i] = _coupled_forward(model, Q[i], V[i], t, "rge-a", None, None, ws,
                                          tols=(tol_q, tol_v))
            except StateError as exc:
                raise StateError(f"state {i} of the batch (row {i} of q and v): {exc}") \
                    from None
        return out
    bad = _run_rows(Q, model.n_v, threads, ws, _couplings.coupled_rows, out, V, TAU)
    if bad >= 0:  # the single call of that row says why
        t = TAU[0] if TAU.shape[0] == 1 else TAU[bad]
        try:
            out[bad] = _coupled_forward(model, Q[bad], V[bad], t, "rge-a", None, None, ws)
        except StateError as exc:
            raise StateError(f"state {bad} of the batch (row {bad} of q and v): {exc}") from None
        raise StateError(f"state {bad} of the batch: qdd not finite")  # (not reached)
    return out


def _inverse_batch(model, ws, q, v, qdd, threads, use_dh=False) -> np.ndarray:
    Q = check_batch(model, "q", q, None)
    B = Q.shape[0]
    V, QDD = check_batch(model, "v", v, B), check_batch(model, "qdd", qdd, B)
    for name, arr in (("q", Q), ("v", V), ("qdd", QDD)):
        if not np.isfinite(arr).all():
            row, col = np.argwhere(~np.isfinite(arr))[0]
            raise StateError(f"{name}[{row}, {col}] = {float(arr[row, col])!r}: not finite (state "
                             f"{row} of the batch)")
    out = np.empty((B, model.n_v))
    bad = _run_rows(Q, model.n_v, threads, ws,
                    _batch.dh_inverse_rows if use_dh else _batch.inverse_rows, out, V, QDD)
    if bad >= 0:
        raise StateError(f"state {bad} of the batch: " + str(overflow_error(
            "tau", q=Q[bad], v=V[bad], qdd=QDD[bad])))
    return out


def _nonfinite_qdd(model, ws, planar, q, v, tau, gim=None, first=False,
                   use_dh=False) -> StateError:
    """The error for a qdd that is NaN or +-inf: the input that is not finite, named; else a
    singular GIM (an elimination pivot that is 0: RGE-A's articulated inertia Ihat, or the
    numerical GIM's factor after GE-N or RGE-N), naming the DOF where the elimination met it
    (RGE-A and RGE-N eliminate from the tip, GE-N, ``first``, from the base); else the recursion
    overflowed. A NaN or Inf in the input always reaches qdd, so only now is it looked for."""
    for name, x in (("q", q), ("v", v), ("tau", tau)):
        if x is not None:
            require_finite(name, np.asarray(x, dtype=float))
    # each free or ball joint's quaternion, normalised by the kernels: zero is no rotation
    free = [(kind, name) for name, kind in zip(model.joint_names, model.joint_types, strict=True)
            if kind in QUATERNION_JOINTS]
    for (kind, name), i in zip(free, model.quaternions.tolist(), strict=True):
        w = np.asarray(q, dtype=float)[i:i + 4]
        with np.errstate(over="ignore", divide="ignore"):
            if not np.isfinite(np.float64(2.0) / (w @ w)):
                return StateError(
                    f"q[{i}:{i + 4}] = {w.tolist()}: the quaternion (w, x, y, z) of {kind} joint "
                    f"{name!r} is zero or too small to normalise (its squared norm underflows): "
                    "it must be a rotation, e.g. [1, 0, 0, 0]")
    if gim is None:
        # Ihat: the planar kernel's column 8, the DH kernel's last column
        pivots = ws.planar[:, 8] if planar else ws.dh_scratch[:, -1] if use_dh else ws.Ihat
    else:
        pivots = np.diag(gim)
    j = first_bad_pivot(pivots, from_base=first, positive=True)
    if j is not None:
        voff = ws.tree.joint_voff
        k = int(np.searchsorted(voff, j, side="right") - 1)
        axis = j - int(voff[k])
        kind, joint = model.joint_types[k], f"joint {model.joint_names[k]!r}"
        return StateError(f"qdd is undefined: the generalized inertia matrix is singular at DOF "
                          f"{j} ({joint}, axis {axis} of its {kind} joint): "
                          f"the inertia about that axis of everything it moves is "
                          f"{float(pivots[j])!r} (a link with no mass or inertia that the axis "
                          "can move, e.g. a point mass on the joint axis, or a length that "
                          "underflows)")
    return overflow_error("qdd", q=q, v=v, tau=tau)


# --------------------------------------------------------------------------- GIM and factors
def mass_matrix(model: Model, q, *, ws: Workspace | None = None) -> np.ndarray:
    """The GIM I(q) (n, n) from composite masses (Eq. 10a); exactly symmetric."""
    door.require_model(model, "mass_matrix")
    q = check_state(model, "q", q)
    ws = _ws(model, ws)
    c = model
    _run_kinematics(c, ws, q, ws.zeros, ws.zeros, ws.no_accel)
    out = np.empty((c.n_v, c.n_v))
    gim_composite(ws.tree, ws.s, out)
    if not np.isfinite(out).all():  # finite q whose composite inertias overflow (|q| ~ 1e160)
        raise overflow_error("the mass matrix", q=q)
    return out


class UDU(NamedTuple):
    """I = U D U^T: U unit upper triangular, D diagonal (Ihat of each axis, eliminated last
    first)."""

    U: np.ndarray
    D: np.ndarray


def udu_factors(model: Model, q, *, ws: Workspace | None = None) -> UDU:
    """The explicit analytic factors I = U D U^T of RGE-A (Appendix A.1), dense (n, n) arrays."""
    door.require_model(model, "udu_factors")
    q = check_state(model, "q", q)
    ws = _ws(model, ws)
    c = model
    _run_kinematics(c, ws, q, ws.zeros, ws.zeros, ws.no_accel)
    rge_a_backward(ws.tree, ws.table_a1, ws.zeros_ro)
    U = np.zeros((c.n_v, c.n_v))
    D = np.zeros((c.n_v, c.n_v))
    udu_assemble(ws.tree, ws.s, U, D)
    if not (np.isfinite(U).all() and np.isfinite(D).all()):  # as forward_dynamics: say why
        j = first_bad_pivot(np.diag(D), from_base=False, positive=True)
        if j is not None and np.isfinite(D[j, j]):
            raise StateError(f"the factors are undefined: the generalized inertia matrix is "
                             f"singular at DOF {j} (its pivot D[{j}, {j}] is "
                             f"{float(D[j, j])!r}: a link with no mass or inertia that the axis "
                             "can move)")
        raise overflow_error("the factors U and D", q=q)
    return UDU(U, D)


class Elimination(NamedTuple):
    """The result of GE-N or RGE-N: qdd, the triangular factor, the multipliers and phi-hat."""

    qdd: np.ndarray
    factor: np.ndarray  # U (GE-N) or L' (RGE-N)
    multipliers: np.ndarray  # L (GE-N) or U' (RGE-N), unit diagonal
    phihat: np.ndarray


def eliminate(gim: np.ndarray, rhs: np.ndarray, method: str) -> Elimination:
    """Solve gim qdd = rhs by GE-N or RGE-N (section 5.2) and return the factors as well.

    Raises StateError for a gim or rhs of the wrong shape or not finite, and for a singular gim
    (a pivot that is 0 or not finite, named with its column: no pivoting, as in the paper)."""
    try:
        A = np.array(gim, dtype=float, copy=True)
        b = np.array(rhs, dtype=float, copy=True)
    except (TypeError, ValueError) as exc:
        raise StateError(f"gim and rhs must be numeric arrays ({exc})") from None
    if b.ndim != 1:
        raise StateError(f"rhs has shape {b.shape}; it must be a vector")
    n = b.shape[0]
    if A.shape != (n, n):
        raise StateError(f"gim has shape {A.shape}; rhs has {n} entries")
    kernels = dict(zip(ELIMINATIONS, (ge_n, rge_n), strict=True))
    if method not in kernels:
        raise FieldError("eliminate", "method", method,
                         f"unknown; choose one of {', '.join(kernels)}")
    if not np.isfinite(A).all():
        i, j = np.argwhere(~np.isfinite(A))[0]
        raise StateError(f"gim[{i}, {j}] = {float(A[i, j])!r}: not finite")
    require_finite("rhs", b)
    mult = np.zeros_like(A)
    x = np.empty(n)
    kernels[method](A, b, mult, x)
    if not np.isfinite(x).all():
        pivots = np.diag(A)  # the factor's diagonal: GE-N eliminates from the first column on,
        c = first_bad_pivot(pivots, from_base=method == "ge-n", positive=False)  # RGE-N the last
        if c is not None:
            raise StateError(f"gim is singular for {method.upper()} (no pivoting): the pivot of "
                             f"column {c} is {float(pivots[c])!r}")
        raise overflow_error("qdd", gim=A, rhs=b)
    return Elimination(x, A, mult, b)


# --------------------------------------------------------------------------- energy and tip
def energy(model: Model, q, v, *, ws: Workspace | None = None) -> tuple[float, float]:
    """(T, V): kinetic and potential energy [J] (V = 0 with every COM at height y = 0)."""
    door.require_model(model, "energy")
    q = check_state(model, "q", q)
    v = check_state(model, "v", v)
    ws = _ws(model, ws)
    c = model
    _run_kinematics(c, ws, q, v, ws.zeros, ws.no_accel)
    T, V = _energy(ws.tree, ws.gravity, ws.s, v)
    if not (math.isfinite(T) and math.isfinite(V)):
        raise overflow_error("the energy", q=q, v=v)
    return float(T), float(V)


def delta_M(model: Model, q, v, E0: float, *, ws: Workspace | None = None) -> float:
    """The energy drift per unit mass (E - E0) / M [J/kg] of Eq. (11)."""
    door.require_model(model, "delta_M")
    E0 = door.number("delta_M", "E0", E0, finite=True)
    T, V = energy(model, q, v, ws=ws)
    return (T + V - E0) / model.total_mass


class Momentum(NamedTuple):
    """The system's momentum in the world frame: ``linear`` [kg m/s], ``angular`` about its
    centre of mass [kg m^2/s] and the centre of mass ``com`` [m]."""

    linear: np.ndarray
    angular: np.ndarray
    com: np.ndarray


def momentum(model: Model, q, v, *, ws: Workspace | None = None) -> Momentum:
    """Linear momentum and angular momentum about the centre of mass G (world frame): with c_k,
    v_k body k's centre of mass and its velocity, R_k its rotation and w_k its angular velocity,
    p = sum m_k v_k and h_G = sum (R_k I_k R_k^T w_k + m_k (c_k - G) x v_k). Without external
    forces (zero gravity, no loads) both are constant: the truths of a floating system."""
    door.require_model(model, "momentum")
    q = check_state(model, "q", q)
    v = check_state(model, "v", v)
    ws = _ws(model, ws)
    _run_kinematics(model, ws, q, v, ws.zeros, ws.no_accel)
    oR, m = ws.oR, model.mass
    r = np.einsum("kij,kj->ki", oR, model.com)  # each centre of mass from its body's origin
    c = ws.oO + r
    w = ws.t[:, :3]
    vc = ws.t[:, 3:] + cross(w, r)
    G = (m[:, None] * c).sum(axis=0) / m.sum()
    linear = (m[:, None] * vc).sum(axis=0)
    spin = np.einsum("kij,kjl,kml,km->i", oR, model.inertia_com, oR, w)  # R I R^T w
    angular = spin + cross(c - G, m[:, None] * vc).sum(axis=0)
    if not (np.isfinite(linear).all() and np.isfinite(angular).all()):
        raise overflow_error("the momentum", q=q, v=v)
    return Momentum(linear, angular, G)


def generalized_momentum(model: Model, q, v, *, ws: Workspace | None = None,
                         gradient: bool = False):
    """p = I(q) v, the generalized momentum (dT/dv), by one kinematics pass and one backward
    pass (:mod:`redysim.algorithms._kernels.momentum`); with ``gradient``, (p, dL/dq): the
    Lagrangian's gradient in q at fixed v, dT/dq - dV/dq, so that along a motion under the
    generalized forces tau, dp/dt = dL/dq + tau. O(n) both, no matrix formed. (A free or ball
    joint's q is a quaternion, not what its rates integrate to: its gradient is refused.)"""
    door.require_model(model, "generalized_momentum")
    if model.cuts:
        raise closed_error(model, "generalized_momentum")
    if gradient and set(QUATERNION_JOINTS) & set(model.joint_types):
        raise FieldError(f"model {model.name!r}", "gradient", True, "dL/dq is taken in the "
                         "joint coordinates the rates integrate to; a free or ball joint's "
                         "quaternion is not one")
    q = check_state(model, "q", q)
    v = check_state(model, "v", v)
    ws = _ws(model, ws)
    tree, s = ws.tree, ws.s
    zero_twists = np.zeros_like(s.t)
    _kinematics(tree, q, v, ws.zeros, ws.no_accel, s)
    p = np.empty(model.n_v)
    # the body momenta M_k t_k summed outboard: inverse dynamics with t := 0, td := t
    rnea_backward(tree, s._replace(t=zero_twists, td=s.t), v, p)
    grad = None
    if gradient:
        grad = np.empty(model.n_v)
        momentum_gradient(tree, s, v, s.W, grad)  # dT/dq, from the momenta H = s.W
        at_rest = np.zeros_like(s.t)
        at_rest[:, 3:] = ws.base_accel  # [0; -g] at every body: the gravity terms dV/dq
        gravity = np.empty(model.n_v)
        rnea_backward(tree, s._replace(t=zero_twists, td=at_rest), ws.zeros, gravity)
        grad -= gravity
    if not (np.isfinite(p).all() and (grad is None or np.isfinite(grad).all())):
        raise overflow_error("the generalized momentum", q=q, v=v)
    return p if grad is None else (p, grad)


class _Point(NamedTuple):
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray | None


class Tip(_Point):
    """The motion of a frame fixed in a body (world frame): the tip of a chain (the distal end
    of its last link), a model's named frame or a body's origin. As a tuple, its point's
    ``position`` [m], ``velocity`` [m/s] and ``acceleration`` [m/s^2] (None without qdd), as it
    always was (``p, v, a = tip(...)``); besides, as attributes, its axes: ``rotation`` (3, 3),
    the frame's axes as columns in world coordinates (MuJoCo's xmat / site_xmat),
    ``angular_velocity`` [rad/s] and ``angular_acceleration`` [rad/s^2] (None without qdd), the
    body's, in world coordinates."""

    rotation: np.ndarray | None
    angular_velocity: np.ndarray | None
    angular_acceleration: np.ndarray | None

    def __new__(cls, position, velocity, acceleration, rotation=None, angular_velocity=None,
                angular_acceleration=None):
        self = super().__new__(cls, position, velocity, acceleration)
        self.rotation = rotation
        self.angular_velocity = angular_velocity
        self.angular_acceleration = angular_acceleration
        return self


TIP = "tip"  # the frame of a chain's tip (a Chain names it so)


def _frame_point(model: Model, frame: str) -> tuple[int, np.ndarray, np.ndarray | None]:
    """(body index, point in the body's frame, the frame's axes in the body's frame or None for
    the body's own) of ``frame``: a frame of the model (``Model.frames``; a chain has ``"tip"``,
    an MJCF model its sites, and its bodies whose origin the importer moved) or a body (its
    origin). Raises FieldError naming the frame and listing the known ones."""
    if isinstance(frame, str) and frame in model.frames:
        b, point = model.frames[frame]
        axes = model.frame_rotations.get(frame)
        return int(b), np.asarray(point, dtype=float), \
            None if axes is None else np.asarray(axes, dtype=float)
    if isinstance(frame, str) and frame in model.body_names:
        return model.body_names.index(frame), np.zeros(3), None
    frames = list(model.frames)
    known = [*frames[:10], *(["..."] if len(frames) > 10 else []), *model.body_names[:10]]
    if model.n_bodies > 10:
        known += ["...", model.body_names[-1]]
    where = "tip" if frame == TIP else "frame"
    raise FieldError(f"{type(model).__name__.lower()} {model.name!r}", where, frame,
                     "no such frame or body; known: " + ", ".join(known)
                     + ("; give another with frame_motion(system, q, v, frame=NAME)"
                        if frame == TIP else ""))


def frame_motion(model: Model, q, v, qdd=None, *, frame: str,
                 ws: Workspace | None = None) -> Tip:
    """A frame's motion in the world frame (:class:`Tip`): its point's position [m], velocity
    [m/s] and, given qdd, acceleration [m/s^2]; its axes (``rotation``), angular velocity
    [rad/s] and, given qdd, angular acceleration [rad/s^2]. ``frame``: a frame of the model
    (``Model.frames``: a chain's ``"tip"``, an MJCF site) or a body's name: its origin as the
    file defines it (an MJCF body's, MuJoCo's xpos and xmat, also where the importer placed the
    body's frame at its joint's anchor or fused the body into its parent). Raises FieldError for
    an unknown frame, StateError for a bad state."""
    door.require_model(model, "frame_motion")
    q = check_state(model, "q", q)
    v = check_state(model, "v", v)
    qdd = check_state(model, "qdd", qdd, optional=True)
    k, point, axes = _frame_point(model, frame)
    ws = _ws(model, ws)
    _run_kinematics(model, ws, q, v, ws.zeros if qdd is None else qdd, ws.no_accel)
    r = _arm(ws.oR[k], point)
    w, v_origin = ws.t[k, :3], ws.t[k, 3:]
    pos = ws.oO[k] + r
    with np.errstate(over="ignore", invalid="ignore"):  # overflow is reported just below
        vel = v_origin + cross(w, r)
        acc = None
        if qdd is not None:
            wd, vd = ws.td[k, :3], ws.td[k, 3:]
            acc = vd + cross(wd, r) + cross(w, cross(w, r))
    if not (np.isfinite(vel).all() and (acc is None or np.isfinite(acc).all())):
        raise overflow_error("the tip's motion" if frame == TIP else f"the motion of {frame!r}",
                             q=q, v=v, qdd=qdd)
    rot = ws.oR[k].copy() if axes is None else ws.oR[k] @ axes
    return Tip(pos, vel, acc, rot, w.copy(), None if qdd is None else ws.td[k, :3].copy())


def _arm(oR: np.ndarray, point: np.ndarray) -> np.ndarray:
    """A body point's offset from the body's origin in the world frame: a point on the body's x
    axis (a chain's tip) as its x times the frame's first column (the chain's formula, whose
    bits the rope's results carry), any other as oR point."""
    if point[1] == 0 and point[2] == 0:
        return point[0] * oR[:, 0]
    return oR @ point


def tip(model: Model, q, v, qdd=None, *, ws: Workspace | None = None) -> Tip:
    """The tip: the frame ``"tip"`` (a chain's is the distal end of its last link): position,
    velocity and, given qdd, acceleration (:func:`frame_motion`; a model without such a frame
    raises FieldError naming the frames it has)."""
    door.require_model(model, "tip")
    return frame_motion(model, q, v, qdd, frame=TIP, ws=ws)


def joint_positions(model: Model, q, *, ws: Workspace | None = None) -> np.ndarray:
    """The joint origins, for plotting a shape: (nb, 3) the body origins (each body's frame sits
    on its joint: a chain's O_1..O_nl), then the frame ``"tip"``'s position when the model has
    one (a chain's distal end), in the world frame [m]."""
    door.require_model(model, "joint_positions")
    q = check_state(model, "q", q)
    ws = _ws(model, ws)
    _run_kinematics(model, ws, q, ws.zeros, ws.zeros, ws.no_accel)
    if TIP not in model.frames:
        return ws.oO.copy()
    b, point = model.frames[TIP]
    return np.vstack([ws.oO, ws.oO[b] + _arm(ws.oR[b], np.asarray(point, dtype=float))])
