"""Reduced and IEEE precision runs of the forward-dynamics kernels (section 5's accuracy study).

"Floating-point accuracy 1e-k" (Tables 8, 10, 11 and A.2) is an ABSOLUTE quantum: every number is
kept to k decimal places, r(x) = round(x / 1e-k) * 1e-k with halves away from zero, applied to the
double-precision inputs and after every operation (docs/design.md, "Reduced precision").
Two arithmetics carry it:

``"double"`` (the default; the paper's)
    IEEE double arithmetic, then r(x) evaluated in double exactly as written, as MATLAB's
    ``round(x / 1e-k) * 1e-k`` does. A product of two k-place numbers that is an exact decimal half
    is, in binary, slightly off the half and rounds by that: 2.50 * 11.77 = 29.425 is
    29.424999999999997 in double and rounds to 29.42. Reproduces all 36 GE-N and RGE-N values of
    Table 10 and all of Table A.2.
``"decimal"``
    Exact decimal arithmetic (stdlib :mod:`decimal`, quantize with ROUND_HALF_UP): the rule as
    docs/design.md states it. Differs from ``"double"`` only at exact decimal ties; in Table 10
    at one: RGE-N at 1e-2 rounds 29.425 up and ends at [-6.25, 7.99, -2.35] instead of the published
    [-6.29, 8.10, -2.46] (35/36). With many places it is exact arithmetic on the double inputs:
    the reference for the IEEE study and the check that the same source runs (50 places equal the
    float64 kernel to 1e-12).

One source of truth. Nothing here re-implements an algorithm: the numba kernels' own Python source
(``kernel.py_func``) runs on object arrays of a rounding number type (:func:`rounded_type`) or on
float32/float16 arrays; :func:`kernel_source` rebinds the module-level names a kernel calls
(``math`` and other jitted kernels, recursively) so that they too stay in the number type. The
kernels allocate nothing and keep their running values in locals initialised from Python float
literals (0.0, 1.0), which numpy treats as weak scalars: a float32 value stays float32 through
them, and the only double operations are on exact zeros and ones (``tests/test_precision.py``
checks that every value a kernel writes stays in the format).

What is rounded, per method:

- GE-N, RGE-N: the double-precision GIM (composite masses) and phi (Newton-Euler) are rounded
  on entry; the elimination runs in the number type (``elimination.py``).
- RGE-A: the chain's link quantities (lengths, masses, inertias about O_k, m c) and q are rounded
  on entry and the recursion runs in the number type: the planar kernel (``planar.py``) for planar
  chains, the spatial kernels otherwise. By default phi is the same rounded double-precision phi
  the other two methods get (passed as tau with gravity and v set to zero: Table A.1 as printed,
  the kernel's bias terms are exact zeros); ``fused_phi=True`` runs the kernel as
  :func:`redysim.forward_dynamics` does, gravity as the base's twist-rate and the velocity terms
  as articulated-body biases, all in the number type. cos and sin are evaluated in double and
  rounded to the number type (to the IEEE format in :func:`ieee_qdd`). Only the geometry of the
  state enters the recursion: rounded arithmetic is not rotation invariant, so q1 matters although
  the GIM does not depend on it.

What reproduces (``reports/precision_tables.py`` prints it value by value): Table 10's GE-N and
RGE-N rows and Table A.2 exactly; Table 10's RGE-A rows only at 1e-1 and two more values (the
paper's ReDySim rounds RGE-A at other points than these kernels do); Table 11's GE-N qdd_1 column
at 6 decimal places, not at the 7 of its caption; Table 8's step counts within 3 % except the
3-link RGE-N and RGE-A runs, whose step counts move by tens with any rounding detail.

The door to the kernels. ``redysim.algorithms._kernels`` is the core's private code; code outside
the core (the harness's 50-digit reference and error study, the reports' operation counts) takes
the kernels' passes from here, by name (:data:`PASSES`): compiled (:func:`kernel_pass`), as
Python source in a number type (:func:`kernel_source`) or with ``math`` replaced by a namespace of
its own (:func:`rebind`), and the digest of their sources for cache keys (:func:`sources_digest`).
The names and the passes' arguments are the contract; the kernels' files are not.

References:
    Agarwal et al., section 5.2-5.3, Tables 8, 10, 11 and A.2; Appendix A.2 (Eq. (A.9)-(A.10)).
    docs/design.md, "Reduced precision".
"""

from __future__ import annotations

import decimal
import functools
import math
import types
from collections.abc import Callable
from decimal import ROUND_HALF_UP, Decimal
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from redysim.algorithms._kernels import sources_digest
from redysim.algorithms._kernels.dh import dh_forward_dynamics, dh_inverse_dynamics
from redysim.algorithms._kernels.elimination import ge_n, rge_n
from redysim.algorithms._kernels.inverse_dynamics import rnea_backward
from redysim.algorithms._kernels.kinematics import kinematics
from redysim.algorithms._kernels.planar import planar_forward_dynamics
from redysim.algorithms._kernels.rge_a import rge_a_backward, rge_a_forward, rge_a_forward_dynamics
from redysim.algorithms._kernels.udu import udu_assemble
from redysim.algorithms.dynamics import METHODS, check_state, mass_matrix, phi
from redysim.algorithms.workspace import bundles_in, kernel_armature
from redysim.model.tree import Model

ARITHMETICS = ("double", "decimal")
IEEE_DTYPES = (np.float16, np.float32, np.float64)
MAX_DECIMALS = 300
MAX_DOUBLE_DECIMALS = 15


# --------------------------------------------------------------------------- the number type
class Rounded:
    """A real number kept to ``decimals`` decimal places: rounded on entry and after every
    +, -, *, /. Concrete types come from :func:`rounded_type`; floats and ints mix in on either
    side (they are rounded on entry). x / 0 gives +-inf and 0 / 0 NaN, as in IEEE."""

    __slots__ = ("v",)
    v: Any  # the value: a float (double arithmetic) or a Decimal
    decimals: int = 0
    arithmetic: str = ""

    if TYPE_CHECKING:  # what every concrete type's __init__ takes (_make_type)
        def __init__(self, x: Any) -> None: ...

    def __float__(self) -> float:
        return float(self.v)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.v!s})"

    def __eq__(self, other) -> bool:
        return type(other) is type(self) and other.v == self.v

    def __hash__(self) -> int:
        return hash(self.v)


_TYPES: dict[tuple[int, str], type] = {}


def rounded_type(decimals: int, arithmetic: str = "double") -> type:
    """The number type of "floating-point accuracy 1e-``decimals``" (cached per arguments)."""
    if isinstance(decimals, bool) or not isinstance(decimals, int | np.integer) \
            or not 0 <= decimals <= MAX_DECIMALS:
        raise ValueError(f"decimals = {decimals!r}: must be an integer in 0..{MAX_DECIMALS}")
    if arithmetic not in ARITHMETICS:
        raise ValueError(f"arithmetic = {arithmetic!r}: choose one of {', '.join(ARITHMETICS)}")
    if arithmetic == "double" and decimals > MAX_DOUBLE_DECIMALS:
        raise ValueError(f"decimals = {decimals}: a double holds ~16 significant digits; beyond "
                         f"{MAX_DOUBLE_DECIMALS} places use arithmetic='decimal'")
    key = (int(decimals), arithmetic)
    if key not in _TYPES:
        _TYPES[key] = (_decimal_type if arithmetic == "decimal" else _double_type)(int(decimals))
    return _TYPES[key]


def _double_type(k: int) -> type:
    quantum = float(f"1e-{k}")  # the double nearest 10^-k, as MATLAB's literal 1e-k
    floor, copysign, isfinite = math.floor, math.copysign, math.isfinite
    inf, nan = math.inf, math.nan

    def r(x: float) -> float:  # MATLAB: round(x / 1e-k) * 1e-k, halves away from zero
        if not isfinite(x):
            return x
        y = x / quantum
        a = abs(y)
        n: float = floor(a)
        if a - n >= 0.5:  # exact: a - floor(a) has no rounding error
            n += 1.0
        return copysign(n, y) * quantum

    def div(a: float, b: float) -> float:
        if b == 0.0:
            return nan if (a == 0.0 or a != a) else copysign(inf, a) * copysign(1.0, b)
        return a / b

    return _make_type(f"Rounded{k}", k, "double", r, float.__add__, float.__sub__, float.__mul__,
                      div, lambda x: float(x))


def _decimal_type(k: int) -> type:
    # enough digits that +, -, * are exact before the quantize for |values| < 1e30
    ctx = decimal.Context(prec=2 * k + 64, rounding=ROUND_HALF_UP, traps=[])
    quantum = Decimal(1).scaleb(-k)

    def r(d: Decimal) -> Decimal:
        return d.quantize(quantum, context=ctx) if d.is_finite() else d

    def to(x) -> Decimal:
        return x if isinstance(x, Decimal) else Decimal(x if isinstance(x, int) else float(x))

    return _make_type(f"Decimal{k}", k, "decimal", r, ctx.add, ctx.subtract, ctx.multiply,
                      ctx.divide, to)


def _make_type(name, k, arithmetic, r, add, sub, mul, div, to):
    new = object.__new__

    def enter(x):
        if type(x) is cls:
            return x.v
        if isinstance(x, Rounded):
            raise TypeError(f"cannot mix {type(x).__name__} with {name}")
        return r(to(x))

    def make(v):
        o = new(cls)
        o.v = r(v)
        return o

    def _init(self, x):
        self.v = enter(x)

    def _binary(op):
        def left(self, other):
            try:
                return make(op(self.v, enter(other)))
            except TypeError:
                return NotImplemented

        def right(self, other):
            try:
                return make(op(enter(other), self.v))
            except TypeError:
                return NotImplemented
        return left, right

    add_l, add_r = _binary(add)
    sub_l, sub_r = _binary(sub)
    mul_l, mul_r = _binary(mul)
    div_l, div_r = _binary(div)
    cls = type(name, (Rounded,), {
        "__slots__": (), "decimals": k, "arithmetic": arithmetic, "__init__": _init,
        "__add__": add_l, "__radd__": add_r, "__sub__": sub_l, "__rsub__": sub_r,
        "__mul__": mul_l, "__rmul__": mul_r, "__truediv__": div_l, "__rtruediv__": div_r,
        "__neg__": lambda self: make(-self.v), "__pos__": lambda self: self,
        "__abs__": lambda self: make(abs(self.v)),
        "__doc__": f"A number kept to {k} decimal places ({arithmetic} arithmetic).",
    })
    return cls


# --------------------------------------------------------------------------- the kernels' passes
# name -> (the compiled kernel, its arguments); tree and s are the bundles of
# redysim.algorithms.workspace (Workspace(model).tree and .s, or bundles_in in another number type)
_PASSES: dict[str, tuple[Callable, str]] = {
    "kinematics": (kinematics, "(tree, q, v, qdd, base_accel, s): rotations, positions, "
                               "motion subspaces, twists and twist-rates into s"),
    "rnea-backward": (rnea_backward, "(tree, s, qdd, tau): Newton-Euler's backward pass after "
                                     "kinematics (with qdd), tau out"),
    "rge-a": (rge_a_forward_dynamics, "(tree, q, v, tau, base_accel, zeros, s, qdd): RGE-A "
                                      "forward dynamics, the three passes"),
    "rge-a-backward": (rge_a_backward, "(tree, s, tau): Table A.1's backward pass"),
    "rge-a-forward": (rge_a_forward, "(tree, s, base_accel, qdd): Table A.1's forward pass"),
    "udu": (udu_assemble, "(tree, s, U, D): I = U D U^T, dense, after the backward pass"),
    "planar": (planar_forward_dynamics, "(length, mass, izz_O, mc_x, mc_y, armature, gravity, q, "
                                        "v, tau, qdd, scratch): RGE-A on a planar chain, scratch "
                                        "(nl, 12)"),
    "dh-forward": (dh_forward_dynamics, "(dh, q, v, tau, base_accel, qdd, scratch): the "
                                        "articulated-body recursion of a robot in DH form, dh "
                                        "its constants (redysim.algorithms.dh_form), scratch "
                                        "(nb, DH_SCRATCH)"),
    "dh-inverse": (dh_inverse_dynamics, "(dh, q, v, qdd, base_accel, tau, scratch): "
                                        "Newton-Euler on a robot in DH form, tau out"),
    "ge-n": (ge_n, "(A, b, mult, x): GE-N, A swept to U, mult = L, b to phihat, x = qdd"),
    "rge-n": (rge_n, "(A, b, mult, x): RGE-N, A swept to L', mult = U', b to phihat, x = qdd"),
}
PASSES: dict[str, str] = {name: args for name, (_, args) in _PASSES.items()}
"""The kernels' passes by name, each with its arguments (arrays written in place)."""


def kernel_pass(name: str) -> Callable:
    """The compiled kernel of the pass ``name`` (:data:`PASSES`), as the core calls it.

    Its Python source, the very function numba compiles, is its ``py_func`` (to compile it with
    other options, or for another dtype).
    """
    try:
        return _PASSES[name][0]
    except (KeyError, TypeError):
        raise ValueError(f"kernel pass {name!r}: unknown; choose one of "
                         f"{', '.join(PASSES)}") from None


_MATH_FUNCS = ("cos", "sin", "tan", "sqrt", "exp", "log", "atan", "atan2", "acos", "asin", "hypot")
_SOURCES: dict = {}


@functools.cache
def _math_for(number) -> types.SimpleNamespace:
    """``math`` whose functions return ``number`` (evaluated in double, then rounded to it)."""
    ns = types.SimpleNamespace(**{n: getattr(math, n) for n in dir(math) if not n.startswith("_")})
    for n in _MATH_FUNCS:
        f = getattr(math, n)
        setattr(ns, n, lambda *args, f=f: number(f(*(float(a) for a in args))))
    return ns


def rebind(name: str, key, math_ns) -> types.FunctionType:
    """The Python source of the pass ``name`` (:data:`PASSES`), run with ``math`` replaced by
    ``math_ns``.

    The kernel's ``py_func`` (the very function numba compiles; a plain helper marks itself with a
    ``py_func`` attribute, as ``joints.sincos`` does) with a copy of its module's globals in which
    ``math`` is ``math_ns`` and every kernel it calls is rebound the same way. Cached per
    ``(pass, key)``; ``key`` (hashable) names the arithmetic. Shared by :func:`kernel_source` and
    :func:`redysim.harness.hiprec.kernel_function` (mpmath's cos and sin).
    """
    return _rebind(kernel_pass(name), key, math_ns)


def _rebind(kernel, key, math_ns):
    fn = _SOURCES.get((kernel, key))
    if fn is None:
        f = getattr(kernel, "py_func", kernel)
        env = dict(f.__globals__)
        env["math"] = math_ns
        fn = types.FunctionType(f.__code__, env, f.__name__, f.__defaults__, f.__closure__)
        fn.__doc__ = f.__doc__
        _SOURCES[(kernel, key)] = fn  # before recursing: a callee may be reached twice
        for name in f.__code__.co_names:
            if hasattr(env.get(name), "py_func"):
                env[name] = _rebind(env[name], key, math_ns)
    return fn


def kernel_source(name: str, number) -> types.FunctionType:
    """The Python source of the pass ``name`` (:data:`PASSES`), run in ``number``'s arithmetic.

    :func:`rebind` with ``math`` whose functions return ``number`` (evaluated in double, then
    converted). ``number``: a :class:`Rounded` type, a numpy scalar type (np.float32, ...) or any
    float-like type the arrays are made of (``redysim.reports.opcount``'s counting float).
    """
    return rebind(name, number, _math_for(number))


def _numbers(a, number) -> np.ndarray:
    """``a`` (array-like of floats) converted to ``number``: an object array of Rounded, or a
    numpy array of the IEEE dtype."""
    a = np.asarray(a, dtype=float)
    if isinstance(number, type) and issubclass(number, Rounded):
        return np.frompyfunc(number, 1, 1)(a).astype(object).reshape(a.shape)
    with np.errstate(over="ignore"):  # float16 holds at most 65504: inf, as IEEE says
        return a.astype(number)


def _empty(shape, number) -> np.ndarray:
    if isinstance(number, type) and issubclass(number, Rounded):
        return np.full(shape, number(0.0), dtype=object)
    return np.zeros(shape, dtype=number)


def _armature(model: Model, number) -> np.ndarray:
    """The model's armature for the kernels' source in ``number`` (empty when it has none:
    :func:`redysim.algorithms.workspace.kernel_armature`): in an IEEE type as the other inputs;
    for a :class:`Rounded` type the doubles themselves, which the kernels' first operation with
    them rounds (a Rounded equals no float, so a Rounded zero would not read as zero)."""
    armature = kernel_armature(model)
    if isinstance(number, type) and issubclass(number, Rounded):
        return np.asarray(armature, dtype=float)
    return _numbers(armature, number)


def _to_float(a) -> np.ndarray:
    return np.asarray(a, dtype=object).astype(float) if np.asarray(a).dtype == object \
        else np.asarray(a, dtype=float)


# --------------------------------------------------------------------------- runners
class Factors(NamedTuple):
    """The factors of one elimination, as in Table A.2 (all float arrays).

    GE-N: I = L U, ``L`` the unit lower multipliers, ``U`` the swept GIM, ``phihat`` = L^-1 phi.
    RGE-N: I = U L, ``U`` the unit upper multipliers (U'), ``L`` the swept GIM (L'),
    ``phihat`` = U'^-1 phi. RGE-A: I = U D U^T, ``U`` unit upper (Eq. A.3-A.4), ``L`` = D U^T
    (the L' of RGE, each product rounded), ``D`` = diag(Ihat); ``phihat`` is None (the kernel keeps
    phitil = D^-1 phihat, not phihat).
    """

    method: str
    L: np.ndarray
    U: np.ndarray
    phihat: np.ndarray | None
    qdd: np.ndarray
    D: np.ndarray | None = None


def _check(model: Model, q, v, tau, method: str):
    if method not in METHODS:
        raise ValueError(f"method = {method!r}: unknown; choose one of {', '.join(METHODS)}")
    q = check_state(model, "q", q)
    v = check_state(model, "v", v)
    tau = check_state(model, "tau", tau, optional=True)
    return q, v, tau


def _eliminate(model, q, v, tau, method, number):
    A = _numbers(mass_matrix(model, q), number)
    b = _numbers(phi(model, q, v, tau), number)
    n = model.n_dof
    mult = _empty((n, n), number)
    x = _empty(n, number)
    with np.errstate(all="ignore"):
        kernel_source(method, number)(A, b, mult, x)  # "ge-n" or "rge-n"
    return A, b, mult, x


def _rge_a(model, q, v, tau, number, fused_phi):
    c, n, nl = model, model.n_dof, model.n_links
    N = lambda a: _numbers(a, number)  # noqa: E731
    if fused_phi:
        gravity, qd_in = c.gravity, v
        tau_in = np.zeros(n) if tau is None else tau
    else:
        gravity, qd_in, tau_in = np.zeros(3), np.zeros(n), phi(c, q, v, tau)
    qdd = _empty(n, number)
    with np.errstate(all="ignore"):
        if c.is_planar:
            kernel_source("planar", number)(
                N(c.length), N(c.mass), N(c.inertia_O[:, 2, 2]), N(c.mass_com[:, 0]),
                N(c.mass_com[:, 1]), _armature(c, number), N(gravity), N(q), N(qd_in),
                N(tau_in), qdd,
                _empty((nl, 12), number))
        else:
            tree, s = bundles_in(c, N, lambda shape: _empty(shape, number),
                                 armature=_armature(c, number))
            kernel_source("rge-a", number)(
                tree, N(q), N(qd_in), N(tau_in), N(-np.asarray(gravity)), _empty(n, number), s,
                qdd)
    return qdd


def reduced_qdd(model: Model, q, v, method: str = "rge-a", decimals: int = 3, *,
                arithmetic: str = "double", tau=None, fused_phi: bool = False) -> np.ndarray:
    """qdd with floating-point accuracy 1e-``decimals`` (section 5.2, Table 10).

    method: ``"ge-n"``, ``"rge-n"`` (on the rounded double GIM and phi) or ``"rge-a"`` (the
    recursion on rounded link quantities, phi rounded as for the others or, with ``fused_phi``,
    computed inside). Returns floats; NaN and +-inf appear where a pivot rounds to zero.
    """
    q, v, tau = _check(model, q, v, tau, method)
    number = rounded_type(decimals, arithmetic)
    if method == "rge-a":
        return _to_float(_rge_a(model, q, v, tau, number, fused_phi))
    return _to_float(_eliminate(model, q, v, tau, method, number)[3])


def reduced_factors(model: Model, q, v, method: str = "ge-n", decimals: int = 3, *,
                    arithmetic: str = "double", tau=None) -> Factors:
    """The factors and phi-hat of the rounded elimination (Table A.2), see :class:`Factors`.

    For ``"rge-a"`` the spatial kernels run (kinematics, Table A.1's backward pass with phi given,
    the U D U^T assembly of ``udu.py``, the forward pass) for any model, planar or not.
    """
    q, v, tau = _check(model, q, v, tau, method)
    number = rounded_type(decimals, arithmetic)
    if method != "rge-a":
        A, b, mult, x = _eliminate(model, q, v, tau, method, number)
        A, b, mult, x = (_to_float(a) for a in (A, b, mult, x))
        if method == "ge-n":
            return Factors(method, mult, A, b, x)
        return Factors(method, A, mult, b, x)
    c, n = model, model.n_dof
    N = lambda a: _numbers(a, number)  # noqa: E731
    E = lambda *s: _empty(s, number)  # noqa: E731
    tree, s = bundles_in(c, N, lambda shape: _empty(shape, number), armature=_armature(c, number))
    qdd, U, D, zeros = E(n), E(n, n), E(n, n), E(n)
    with np.errstate(all="ignore"):  # v = 0 and no gravity: t = td = 0 (Table A.1 as printed)
        kernel_source("kinematics", number)(tree, N(q), zeros, zeros, E(3), s)
        kernel_source("rge-a-backward", number)(tree, s, N(phi(c, q, v, tau)))
        kernel_source("udu", number)(tree, s, U, D)
        kernel_source("rge-a-forward", number)(tree, s, E(3), qdd)
        L = s.Ihat[:, None] * U.T  # L' = D U^T, each product rounded
    return Factors(method, _to_float(L), _to_float(U), None, _to_float(qdd), _to_float(D))


def ieee_qdd(model: Model, q, v, method: str = "rge-a", dtype=np.float32, *, tau=None,
             fused_phi: bool = False) -> np.ndarray:
    """qdd computed by the same kernel source in an IEEE format (float16, float32, float64).

    The inputs (GIM and phi for GE-N/RGE-N; link quantities, q and phi for RGE-A) are the
    double-precision ones rounded to ``dtype``; every operation then rounds to ``dtype``
    (numpy scalar arithmetic). Overflow gives inf (float16 holds at most 65504).
    """
    q, v, tau = _check(model, q, v, tau, method)
    number = np.dtype(dtype).type
    if number not in IEEE_DTYPES:
        raise ValueError(f"dtype = {dtype!r}: choose float16, float32 or float64")
    if method == "rge-a":
        return _rge_a(model, q, v, tau, number, fused_phi)
    return _eliminate(model, q, v, tau, method, number)[3]


__all__ = ["ARITHMETICS", "Factors", "IEEE_DTYPES", "METHODS", "PASSES", "Rounded", "ieee_qdd",
           "kernel_pass", "kernel_source", "rebind", "reduced_factors", "reduced_qdd",
           "rounded_type", "sources_digest"]
