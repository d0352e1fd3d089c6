"""Evaluators: a model's dynamics bound once, for the fastest call from Python on small systems.

``fd = redysim.evaluator(model)`` returns a function ``fd(q, v, tau=None, out=None) -> qdd``
equal bit for bit to :func:`redysim.forward_dynamics` ``(model, q, v, tau, out=out)``;
``kind="inverse_dynamics"`` returns ``id(q, v, qdd, out=None) -> tau``, equal to
:func:`redysim.inverse_dynamics`. What :func:`~redysim.forward_dynamics` does at every call
(look up the thread's workspace, choose the kernel, numba's dispatch of seven arrays) is done
once here. The function is a CPython builtin (:mod:`redysim.algorithms._kernels.binding`) whose
C function, generated for the model's lean entry (:mod:`redysim.algorithms._kernels.lean`),
takes its arguments, checks that each vector is a 1-D aligned native float64 ndarray (``out``
writeable), makes the result vector when ``out`` is None and calls the entry with the
evaluator's own scratch; the entry checks lengths and strides. Anything else (lists, float32,
strided or read-only ``out``, a wrong length, a batch of states, a result that is not finite,
other keyword names) goes to the checked path, the public function itself, called with the same
arguments: the same conversions, the same errors (StateError naming the argument and its
length), the same results. ``fd.__self__.model`` and ``fd.__self__.kind`` say what it computes.

Thread safety: an evaluator holds one scratch, and its compiled call holds the GIL (releasing
it costs more than it saves at this size: docs/design.md, "Performance notes"), so calls from
several threads on one evaluator are safe and run one at a time; the checked path uses the
model's own workspace of each calling thread. For states in parallel give
:func:`~redysim.forward_dynamics` a batch. An evaluator cannot be pickled: make one in each
process. With numba disabled (``NUMBA_DISABLE_JIT``), or where NumPy's structs are not as the
builtin reads them, the evaluator is the checked path.

What a call costs, against the public function's and Pinocchio's: ``benchmarks/lean_call.py``
(docs/notes/2026-11-evaluator-and-ladder.md).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from redysim._jit import JIT_ENABLED
from redysim.algorithms._kernels import binding as _binding
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
from redysim.model import door
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

    Refuses (:class:`~redysim.errors.ModelTypeError`, a TypeError and a FieldError)
    something that is not a Model, (FieldError) an unknown ``kind``, and (CaseError)
    a model with cut joints, as the public functions refuse it. A coupled model
    (:meth:`~redysim.Model.with_couplings`): forward dynamics keeps its couplings (a lean entry
    with them in RGE-A's recursion, on a spatial tree; a state off them goes to the checked
    path, which names the joint); its inverse dynamics, and a planar one's, is the checked
    path. Building one compiles its
    kernel on first use in a process (loaded from numba's disk cache after that) and allocates
    the evaluator's scratch (a :class:`~redysim.algorithms.workspace.Workspace`, ~380 bytes a
    DOF), kept as long as the evaluator is.
    """
    door.require_model(model, "evaluator")
    if kind not in KINDS:
        raise FieldError("evaluator", "kind", kind, f"must be one of {', '.join(KINDS)}")
    if model.cuts:
        raise closed_error(model, f"evaluator(kind={kind!r})")
    ws = Workspace(model)
    serial = bool(ws.tree.serial)
    use_dh = use_dh_kernels(model, ws.dh, dh, model.is_planar)
    forward = kind == "forward_dynamics"
    if forward:
        entry = ((_lean.FORWARD_COUPLED_CHAIN if serial else _lean.FORWARD_COUPLED_TREE)
                 if ws.coupled else
                 _lean.FORWARD_PLANAR if model.is_planar else _lean.FORWARD_DH if use_dh else
                 _lean.FORWARD_CHAIN if serial else _lean.FORWARD_TREE)
        checked, params, result = _checked_forward(model, use_dh), "q, v, tau=None, out=None", "qdd"
    else:
        entry = (_lean.INVERSE_DH if use_dh else _lean.INVERSE_CHAIN if serial
                 else _lean.INVERSE_TREE)
        checked, params, result = _checked_inverse(model, use_dh), "q, v, qdd, out=None", "tau"
    doc = (f"{kind}({params})\n--\n\n{result} of {type(model).__name__.lower()} "
           f"{model.name!r}, bit for bit redysim.{kind}'s (redysim.evaluator).")
    checked.__name__ = kind  # (named in the errors it raises)
    # a coupled model's lean entry: forward dynamics on a spatial tree (RGE-A with the couplings
    # in its recursion); its inverse dynamics and a planar one's forward, the checked path
    lean = not model.couplings or (forward and ws.coupled)
    builtin = (_binding.bind(entry, forward, ws, checked, model, kind, doc)
               if lean and _binding.BINDING_OK and JIT_ENABLED else None)
    if builtin is not None:
        return builtin
    # numba disabled, NumPy's structs not as the binding reads them, or no lean entry for a
    # coupled model: the checked path, with the builtin's docstring and __self__
    checked.__doc__ = doc.split("--\n\n", 1)[1]
    checked.__dict__["__self__"] = _binding.Bound.of_checked_path(model, kind)
    return checked


def _checked_forward(model: Model, dh: bool) -> Callable[..., np.ndarray]:
    """The evaluator's checked path: the public function (looked up at each call)."""

    def checked(q, v, tau=None, out=None):
        return forward_dynamics(model, q, v, tau, out=out, dh=dh)

    return checked


def _checked_inverse(model: Model, dh: bool) -> Callable[..., np.ndarray]:
    """As :func:`_checked_forward`; ``out`` filled here (inverse_dynamics takes none)."""

    def checked(q, v, qdd, out=None):
        tau = inverse_dynamics(model, q, v, qdd, dh=dh)
        if out is None:
            return tau
        out = check_out(model, out)  # (StateError for an out of another shape: a batch's too)
        out[:] = tau
        return out

    return checked
