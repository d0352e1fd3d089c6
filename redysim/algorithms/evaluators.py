"""Evaluators: a model's dynamics bound once, for the fastest call from Python on small systems.

``fd = redysim.evaluator(model)`` returns a function ``fd(q, v, tau=None, out=None) -> qdd``
equal bit for bit to :func:`redysim.forward_dynamics` ``(model, q, v, tau, out=out)``;
``kind="inverse_dynamics"`` returns ``id(q, v, qdd, out=None) -> tau``, equal to
:func:`redysim.inverse_dynamics`. What :func:`~redysim.forward_dynamics` does at every call
(look up the thread's workspace, choose the kernel, numba's dispatch of seven arrays) is done
once here: a call hands its arrays, with the evaluator's own scratch, to one compiled function
of its own (:mod:`redysim.algorithms._kernels.lean`), past numba's dispatch; that function's
unboxing checks that each is a 1-D aligned native float64 ndarray (``out`` writeable), and its
kernel checks their lengths and strides. Anything else
(lists, float32, strided or read-only ``out``, a wrong length, a batch of states, a result that
is not finite) takes the checked path, the public function itself: the same conversions, the
same errors (StateError naming the argument and its length), the same results.

Thread safety: an evaluator holds one scratch, and its compiled call holds the GIL (releasing
it costs more than it saves at this size: docs/design.md, "Performance notes"), so calls from
several threads on one evaluator are safe and run one at a time; the checked path uses the
model's own workspace of each calling thread. For states in parallel give
:func:`~redysim.forward_dynamics` a batch. An evaluator cannot be pickled: make one in each
process.

Measured per call from Python on this project's VM (``benchmarks/lean_call.py``; docs/design.md,
"Performance notes").
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from redysim.algorithms._kernels import lean as _lean
from redysim.algorithms.dynamics import (
    check_out,
    closed_error,
    forward_dynamics,
    inverse_dynamics,
    use_dh_kernels,
)
from redysim.algorithms.workspace import Workspace
from redysim.errors import FieldError
from redysim.model.tree import Model

KINDS = ("forward_dynamics", "inverse_dynamics")


def evaluator(model: Model, kind: str = "forward_dynamics", *,
              dh: bool | None = None) -> Callable[..., np.ndarray]:
    """A function computing ``kind`` on ``model`` as fast as a call from Python can (module
    docstring): ``fd(q, v, tau=None, out=None) -> qdd`` for ``"forward_dynamics"`` (RGE-A, the
    planar kernel for a planar chain or the DH kernels for a robot in DH form, as
    :func:`redysim.forward_dynamics` chooses), or
    ``id(q, v, qdd, out=None) -> tau`` for ``"inverse_dynamics"``. The result is ``out`` when
    given, else a new array; the same bits as the public function's. ``dh``: as the public
    functions take it (False: the general kernels on a robot in DH form).

    Refuses (FieldError) something that is not a Model and an unknown ``kind``, and (CaseError)
    a model with cut joints, as the public functions refuse it. Building one compiles its
    kernel on first use in a process (loaded from numba's disk cache after that) and allocates
    the evaluator's scratch (a :class:`~redysim.algorithms.workspace.Workspace`, ~380 bytes a
    DOF), kept as long as the evaluator is.
    """
    if not isinstance(model, Model):
        raise FieldError("evaluator", "model", type(model).__name__,
                         "must be a redysim.Model (Chain.uniform, load_model(...), ...)")
    if kind not in KINDS:
        raise FieldError("evaluator", "kind", kind, f"must be one of {', '.join(KINDS)}")
    if model.cuts:
        raise closed_error(model, f"evaluator(kind={kind!r})")
    if model.couplings:
        raise FieldError("evaluator", "model", model.name, "a coupled model (its couplings: "
                         f"{', '.join(c.follower for c in model.couplings)}): the lean entries "
                         "run the tree's recursions only; call redysim.forward_dynamics or "
                         "inverse_dynamics, which keep the couplings")
    ws = Workspace(model)
    serial = bool(ws.tree.serial)
    use_dh = use_dh_kernels(model, ws.dh, dh, model.is_planar)
    if kind == "forward_dynamics":
        entry = (_lean.FORWARD_PLANAR if model.is_planar else _lean.FORWARD_DH if use_dh else
                 _lean.FORWARD_CHAIN if serial else _lean.FORWARD_TREE)
        return _forward(model, ws, _lean_call(entry), use_dh)
    entry = (_lean.INVERSE_DH if use_dh else _lean.INVERSE_CHAIN if serial
             else _lean.INVERSE_TREE)
    return _inverse(model, ws, _lean_call(entry), use_dh)


def _lean_call(entry):
    """The entry's compiled wrapper, past numba's dispatch (module docstring); None with
    numba disabled, or where NumPy's structs are not as its unboxing reads them."""
    return entry.call if _lean.NUMPY_LAYOUT_OK else None


def _forward(model: Model, ws: Workspace, call, dh: bool) -> Callable[..., np.ndarray]:
    f, i, s, zeros, n = ws.kernel_f, ws.kernel_i, ws.scratch, ws.zeros, model.n_v
    empty, Refused = np.empty, _lean.Refused
    if call is None:  # numba disabled, or NumPy's structs not as the entries read them
        return _named(lambda q, v, tau=None, out=None: forward_dynamics(model, q, v, tau, out=out,
                                                                        dh=dh),
                      model, "forward_dynamics", "(q, v, tau=None, out=None) -> qdd")

    def fd(q, v, tau=None, out=None):
        # The compiled call's own unboxing refuses (TypeError) what is not a 1-D aligned native
        # float64 ndarray, or a read-only out (lean.CheckedVector); its kernel refuses
        # (Refused) a length, a stride or a result that is not finite
        try:
            return call(q, v, zeros if tau is None else tau, empty(n) if out is None else out,
                        f, i, s)
        except (TypeError, Refused):
            return forward_dynamics(model, q, v, tau, out=out, dh=dh)

    return _named(fd, model, "forward_dynamics", "(q, v, tau=None, out=None) -> qdd")


def _inverse(model: Model, ws: Workspace, call, dh: bool) -> Callable[..., np.ndarray]:
    f, i, s, n = ws.kernel_f, ws.kernel_i, ws.scratch, model.n_v
    empty, Refused = np.empty, _lean.Refused

    def checked(q, v, qdd, out=None):
        tau = inverse_dynamics(model, q, v, qdd, dh=dh)
        if out is None:
            return tau
        out = check_out(model, out)  # (StateError for an out of another shape: a batch's too)
        out[:] = tau
        return out

    if call is None:  # numba disabled, or NumPy's structs not as the entries read them
        return _named(checked, model, "inverse_dynamics", "(q, v, qdd, out=None) -> tau")

    def id_(q, v, qdd, out=None):
        try:  # (as fd's, _forward)
            return call(q, v, qdd, empty(n) if out is None else out, f, i, s)
        except (TypeError, Refused):
            return checked(q, v, qdd, out)

    return _named(id_, model, "inverse_dynamics", "(q, v, qdd, out=None) -> tau")


def _named(func, model: Model, kind: str, signature: str):
    func.__name__ = func.__qualname__ = kind
    func.__doc__ = (f"{kind}{signature} of {type(model).__name__.lower()} {model.name!r}, "
                    f"bit for bit redysim.{kind}'s (redysim.evaluator).")
    func.model, func.kind = model, kind
    return func
