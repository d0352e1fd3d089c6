"""A high-precision reference for qdd: the core's own RGE-A kernel, run in mpmath arithmetic.

The true error of a forward-dynamics method is ||qdd_method - qdd_exact|| / ||qdd_exact||, where
qdd_exact solves I(q) qdd = phi(q, v, tau) exactly for the double-precision input (the chain's
doubles: lengths, masses, COMs, inertias about the COM, gravity; the doubles q, v, tau). This
module computes qdd_exact to ~40+ significant digits in O(n), so it reaches 100,000-link chains.

How (one source of truth): the core's numba kernels are plain Python underneath, and the core
hands out their passes by name (:mod:`redysim.algorithms.precision`, its door to the kernels).
:func:`kernel_function` takes a pass's Python source (``dispatcher.py_func``: the same code object)
and gives it a copy of its module's globals in which

- every jitted callee (``kinematics``, ``jcalc``, ``column_mass``, ``rge_a_backward`` ...) is
  replaced by its own rebound Python function, and
- ``math`` (used only for ``math.cos``/``math.sin`` in ``joints.jcalc`` and ``planar``) is replaced
  by a namespace whose cos/sin are those of the target arithmetic (mpmath's, at the working
  precision).

Fed object arrays of ``mpmath.mpf``, the kernel then runs entirely in mpmath arithmetic: Table
A.1's recursion with the articulated masses carried as the symmetric blocks [[X, Y], [Y^T, Z]],
axis by axis, exactly as the compiled kernel does it, only with 50 digits (``dps=50``). No kernel
was changed for this; the compiled path is untouched. The same mechanism runs the kernels in
IEEE single precision (:data:`FLOAT32`, numpy float32 scalars; numpy 2's weak Python scalars keep
the kernels' float literals from promoting), which gives the error study its float32 RGE-A.

What is exact and what is not: the derived per-link quantities the kernel reads (inertia about
O_k by the parallel-axis theorem, m c) are recomputed here in the target arithmetic from the
chain's primary doubles (:func:`chain_arrays`); the double-precision ``chain.inertia_O`` carries a
rounding of its own, which is part of the float64 methods' error, not of the problem.

Verified (tests/test_hiprec.py): against :func:`dense_reference`, an independent O(n^3) mpmath
solution (its own kinematics with Rodrigues rotations, Newton-Euler about the centres of mass
rather than DeNOC, the GIM column by column as I e_i, ``mpmath.lu_solve``) on R, U, S and mixed
chains of 1..15 links at random states (agreement ~1e-45 at dps = 50); against
``numpy.linalg.solve(GIM, phi)`` on small well-conditioned chains; the planar kernel in mpmath
against the spatial one; dps = 50 against dps = 70 on long stretched chains (the reference's own
digits); and the Python path in float64 against the compiled kernel.

Cost: O(n) time, milliseconds a link at dps = 50 in pure-Python mpmath (no gmpy2), so 100,000
U-links take minutes (docs/notes/2026-11-costs-in-the-code.md). O(n) memory (object arrays).

References:
    Agarwal et al., Appendix A.1, Table A.1 (the recursion); Eq. (9)-(12) (phi).
    mpmath: F. Johansson et al., arbitrary-precision floating-point arithmetic for Python.
"""

from __future__ import annotations

import contextlib
import math
import types
from collections.abc import Callable
from dataclasses import dataclass, field

import mpmath
import numpy as np

from redysim import Chain, Model
from redysim.algorithms.precision import rebind
from redysim.algorithms.workspace import bundles_in, kernel_armature

DEFAULT_DPS = 50


# --------------------------------------------------------------------------- arithmetics
@dataclass(frozen=True)
class Arithmetic:
    """A number system to run the kernels' Python source in.

    name:     label ("mpf50", "float32", "float64").
    scalar:   converts a Python/numpy double to the scalar type (exactly, for mpf).
    dtype:    numpy dtype of the arrays (``object`` for mpf).
    cos, sin: the trigonometric functions the kernels see as ``math.cos``/``math.sin``.
    dps:      decimal digits of the mpmath working precision (0 for IEEE types).
    """

    name: str
    scalar: Callable
    dtype: object
    cos: Callable
    sin: Callable
    dps: int = 0
    trig: types.SimpleNamespace = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "trig", types.SimpleNamespace(cos=self.cos, sin=self.sin))

    def context(self):
        """The working-precision context (mpmath.workdps) or a null context."""
        return mpmath.workdps(self.dps) if self.dps else contextlib.nullcontext()

    def array(self, a) -> np.ndarray:
        """``a`` (doubles) converted element by element."""
        a = np.asarray(a, dtype=float)
        if self.dtype is object:
            out = np.empty(a.shape, dtype=object)
            flat_in, flat_out = a.ravel(), out.reshape(-1)
            for i in range(flat_in.size):
                flat_out[i] = self.scalar(float(flat_in[i]))
            return out
        return a.astype(self.dtype)

    def zeros(self, shape) -> np.ndarray:
        return self.array(np.zeros(shape))


def mpf_arithmetic(dps: int = DEFAULT_DPS) -> Arithmetic:
    """mpmath arithmetic with ``dps`` significant decimal digits (conversion of doubles exact)."""
    return Arithmetic(f"mpf{dps}", mpmath.mpf, object, mpmath.cos, mpmath.sin, dps)


def _f32_cos(x):
    return np.float32(math.cos(x))


def _f32_sin(x):
    return np.float32(math.sin(x))


FLOAT32 = Arithmetic("float32", np.float32, np.float32, _f32_cos, _f32_sin)
"""IEEE single precision: every operation on numpy float32 scalars (trig correctly rounded to
float32 from the double result)."""
FLOAT64 = Arithmetic("float64", float, np.float64, math.cos, math.sin)
"""IEEE double precision through the Python source (a check of the rebinding itself)."""


# --------------------------------------------------------------------------- rebinding
def kernel_function(name: str, arith: Arithmetic) -> types.FunctionType:
    """The Python source of the kernels' pass ``name`` (``"rge-a"``, ``"planar"``, ...: the
    names of :data:`redysim.algorithms.precision.PASSES`), rebound to run in ``arith``.

    Same code object as the compiled kernel's ``py_func``; globals: a copy of the kernel module's,
    with every kernel it calls rebound (recursively) and ``math`` replaced by ``arith.trig``
    (:func:`redysim.algorithms.precision.rebind`, the mechanism the reduced-precision study uses
    too). The module itself is not touched.
    """
    return rebind(name, ("hiprec", arith.name), arith.trig)


# --------------------------------------------------------------------------- chain and state
def chain_arrays(model: Model, arith: Arithmetic) -> dict[str, np.ndarray]:
    """The per-body arrays the kernels read, recomputed in ``arith`` from the model's doubles.

    mass: converted; inertia_O = I_C + m (|c|^2 1 - c c^T) and mass_com = m c computed in ``arith``
    from mass, com and inertia_com (exact at dps = 50: the products of doubles need ~32 digits).
    dof_u: for mpf, each axis re-normalised at the working precision (a general axis stored as a
    double is a unit vector only to ~1e-16, and Rodrigues' formula is a rotation only for a unit
    axis; the exact problem takes the double vector's direction). Coordinate axes are exactly
    (1, 0, 0) etc. either way. ``length``: a chain's link lengths (a chain only: any other
    model's placements are taken as they are, converted).
    """
    with arith.context():
        m = arith.array(model.mass)
        c = arith.array(model.com)
        ic = arith.array(model.inertia_com)
        nl = model.n_bodies
        inertia_O = np.empty((nl, 3, 3), dtype=arith.dtype)
        mass_com = np.empty((nl, 3), dtype=arith.dtype)
        for k in range(nl):
            ck = c[k]
            sq = ck[0] * ck[0] + ck[1] * ck[1] + ck[2] * ck[2]
            for i in range(3):
                mass_com[k, i] = m[k] * ck[i]
                for j in range(3):
                    par = (sq if i == j else 0.0) - ck[i] * ck[j]
                    inertia_O[k, i, j] = ic[k, i, j] + m[k] * par
        dof_u = arith.array(model.dof_u)
        if arith.dps:
            for j in range(dof_u.shape[0]):
                u = dof_u[j]
                norm = mpmath.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
                dof_u[j] = [u[0] / norm, u[1] / norm, u[2] / norm]
        out = {"mass": m, "inertia_O": inertia_O, "mass_com": mass_com, "dof_u": dof_u}
        if isinstance(model, Chain):
            out["length"] = arith.array(model.length)
        return out


def _state(model, arith, q, v, tau):
    n = model.n_dof
    q = arith.array(np.asarray(q, dtype=float).reshape(n))
    v = arith.array(np.asarray(v, dtype=float).reshape(n))
    tau = arith.zeros(n) if tau is None else arith.array(np.asarray(tau, float).reshape(n))
    return q, v, tau


# --------------------------------------------------------------------------- kernels in arith
def rge_a_qdd(model: Model, q, v, tau=None, arith: Arithmetic | None = None) -> np.ndarray:
    """qdd by the core's spatial RGE-A kernel (``rge_a_forward_dynamics``) run in ``arith``.

    Returns an array of ``arith``'s scalars (object array of mpf, or float32).
    """
    arith = arith or mpf_arithmetic()
    c = model
    n = c.n_dof
    fd = kernel_function("rge-a", arith)
    with arith.context():
        tree, s = _bundles(c, arith)
        q, v, tau = _state(c, arith, q, v, tau)
        qdd = arith.zeros(n)
        fd(tree, q, v, tau, arith.array(-c.gravity), arith.zeros(n), s, qdd)
    return qdd


def _bundles(model: Model, arith: Arithmetic):
    """The kernels' Tree and Scratch bundles in ``arith``, the tree's arrays from
    :func:`chain_arrays` (a chain's placements from its lengths, any other model's converted)."""
    a = chain_arrays(model, arith)
    extra = {"along": np.concatenate((arith.zeros(1), a["length"][:-1]))} if "length" in a else {}
    return bundles_in(model, arith.array, arith.zeros, mass=a["mass"], inertia_O=a["inertia_O"],
                      mass_com=a["mass_com"], dof_u=a["dof_u"], **extra)


def planar_qdd(chain: Chain, q, v, tau=None, arith: Arithmetic | None = None) -> np.ndarray:
    """qdd by the core's planar kernel (``planar_forward_dynamics``) run in ``arith``.

    ``chain``: a planar serial chain (:attr:`redysim.Model.is_planar`: a chain of links whose
    joints each turn about z; ValueError for any other model), whose link lengths the kernel
    reads."""
    if not chain.is_planar:
        raise ValueError(f"chain {chain.name!r} is not planar")
    arith = arith or mpf_arithmetic()
    c = chain
    fd = kernel_function("planar", arith)
    with arith.context():
        a = chain_arrays(c, arith)
        q, v, tau = _state(c, arith, q, v, tau)
        qdd = arith.zeros(c.n_dof)
        fd(a["length"], a["mass"], a["inertia_O"][:, 2, 2].copy(),
           a["mass_com"][:, 0].copy(), a["mass_com"][:, 1].copy(),
           arith.array(kernel_armature(c)),
           arith.array(c.gravity),
           q, v, tau, qdd, arith.zeros((c.n_links, 12)))
    return qdd


def kinematics_and_phi(model: Model, q, v, tau=None, arith: Arithmetic | None = None):
    """(oR, oO, oP, phi, arrays) from the core's kinematics and Newton-Euler kernels in ``arith``
    (qdd = 0, base at -g); ``arrays`` is :func:`chain_arrays`. For study kernels that need the
    same inputs as RGE-A in another arithmetic (``redysim.harness.nonsymmetric``)."""
    arith = arith or mpf_arithmetic()
    c = model
    n = c.n_dof
    kin = kernel_function("kinematics", arith)
    rnea = kernel_function("rnea-backward", arith)
    with arith.context():
        a = chain_arrays(c, arith)
        tree, s = _bundles(c, arith)
        q, v, tau = _state(c, arith, q, v, tau)
        kin(tree, q, v, arith.zeros(n), arith.array(-c.gravity), s)
        bias = arith.zeros(n)
        rnea(tree, s, arith.zeros(n), bias)
        phi = tau - bias
    return s.oR, s.oO, s.oP, phi, a


# --------------------------------------------------------------------------- the reference
def qdd_reference(model: Model, q, v, tau=None, dps: int = DEFAULT_DPS, *,
                  output: str = "float"):
    """The exact qdd of the double-precision input, to ~dps - 10 digits, in O(n).

    model, q, v, tau: as for :func:`redysim.forward_dynamics` (tau default zero); every double
    is taken as exact. dps: mpmath's decimal digits (50: qdd good to ~40 digits even where
    cond2(GIM) ~ 1e20).
    output: ``"float"`` -> numpy float64 array (each value correctly rounded);
            ``"mpf"`` -> list of mpmath.mpf (at ``dps``);
            ``"dd"`` -> (n, 2) float64 array [hi, lo], hi + lo = qdd to ~32 digits (a
            double-double: what the error study caches on disk, see :func:`to_double_double`).
    """
    arith = mpf_arithmetic(dps)
    qdd = rge_a_qdd(model, q, v, tau, arith)
    if output == "mpf":
        return list(qdd)
    if output == "float":
        return np.array([float(x) for x in qdd])
    if output == "dd":
        return to_double_double(qdd)
    raise ValueError(f"output = {output!r}: choose 'float', 'mpf' or 'dd'")


def to_double_double(values) -> np.ndarray:
    """(n, 2) [hi, lo] with hi = round(x), lo = round(x - hi): x to ~106 bits (~32 digits)."""
    out = np.empty((len(values), 2))
    for i, x in enumerate(values):
        hi = float(x)
        out[i, 0] = hi
        out[i, 1] = float(x - mpmath.mpf(hi))
    return out


def relative_errors(qdd, ref_dd: np.ndarray) -> tuple[float, float]:
    """(||e||_2 / ||ref||_2, ||e||_inf / ||ref||_inf) of a method's qdd against a double-double
    reference (n, 2); e = (qdd - hi) - lo in float64 (qdd - hi is exact where they agree to a
    factor 2). NaN when qdd has a NaN or Inf."""
    x = np.asarray(qdd, dtype=float)
    if not np.all(np.isfinite(x)):
        return math.nan, math.nan
    hi, lo = ref_dd[:, 0], ref_dd[:, 1]
    e = (x - hi) - lo
    return (float(np.linalg.norm(e) / np.linalg.norm(hi)),
            float(np.abs(e).max() / np.abs(hi).max()))


# --------------------------------------------------------------------------- independent check
def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _add(a, b):
    return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]


def _scale(s, a):
    return [s * a[0], s * a[1], s * a[2]]


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _matvec(R, v):
    return [R[i][0] * v[0] + R[i][1] * v[1] + R[i][2] * v[2] for i in range(3)]


def _matmul(A, B):
    return [[sum(A[i][k] * B[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def _transpose(A):
    return [[A[j][i] for j in range(3)] for i in range(3)]


def _rodrigues(u, angle):
    """Rot(u, angle) = c 1 + s C(u) + (1 - c) u u^T, u a unit vector."""
    c, s = mpmath.cos(angle), mpmath.sin(angle)
    t = 1 - c
    return [[c + t * u[0] * u[0], t * u[0] * u[1] - s * u[2], t * u[0] * u[2] + s * u[1]],
            [t * u[1] * u[0] + s * u[2], c + t * u[1] * u[1], t * u[1] * u[2] - s * u[0]],
            [t * u[2] * u[0] - s * u[1], t * u[2] * u[1] + s * u[0], c + t * u[2] * u[2]]]


def newton_euler_mp(chain: Model, q, v, qdd, *, gravity: bool = True) -> list:
    """tau = I qdd + C v + (gravity terms if ``gravity``): textbook Newton-Euler about the
    centres of mass, in mpmath at the current precision. Independent of the core's kernels
    (no DeNOC matrices, no articulated masses); revolute axes only (R, U, S, general R), serial
    models (a chain, or any model whose body k hangs from body k - 1: a protein backbone).

    Forward: a_O of each joint origin (fixed in the parent), w and wd axis by axis; backward:
    F = m a_C, N = I_C wd + w x (I_C w), moments about O_k, tau_j = e_j . n_k.
    """
    mpf = mpmath.mpf
    nl = chain.n_bodies
    if any(int(p) != k - 1 for k, p in enumerate(chain.parent)):
        raise NotImplementedError("dense_reference: serial models only (body k on body k - 1)")
    q, v, qdd = ([mpf(float(x)) for x in vec] for vec in (q, v, qdd))
    zero3 = [mpf(0)] * 3
    R = [[mpf(1) if i == j else mpf(0) for j in range(3)] for i in range(3)]
    O, w, wd = zero3, zero3, zero3
    aO = [-mpf(float(g)) for g in chain.gravity] if gravity else zero3
    links = []
    j = 0
    # forward: k = 1..nl
    for k in range(nl):
        # joint k's placement in body k - 1 (a chain's: its parent's length along x)
        r = _matvec(R, [mpf(float(x)) for x in chain.placement_p[k]])
        aO = _add(aO, _add(_cross(wd, r), _cross(w, _cross(w, r))))
        O = _add(O, r)
        R = _matmul(R, [[mpf(float(x)) for x in row] for row in chain.placement_R[k]])
        axes = []
        for kind, u in chain.joints[k].axes():
            if kind != "R":
                raise NotImplementedError("dense_reference: revolute axes only")
            um = [mpf(float(x)) for x in u]
            norm = mpmath.sqrt(_dot(um, um))  # exactly unit at the working precision
            um = _scale(1 / norm, um)
            e = _matvec(R, um)
            wd = _add(wd, _add(_scale(qdd[j], e), _cross(w, _scale(v[j], e))))
            w = _add(w, _scale(v[j], e))
            R = _matmul(R, _rodrigues(um, q[j]))
            axes.append((j, e))
            j += 1
        links.append((R, O, w, wd, aO, axes))
    # backward: k = nl..1
    tau = [mpf(0)] * chain.n_dof
    f, n = zero3, zero3
    O_next = None
    for k in range(nl - 1, -1, -1):
        R, O, w, wd, aO, axes = links[k]
        m = mpf(float(chain.mass[k]))
        c = _matvec(R, [mpf(float(x)) for x in chain.com[k]])
        aC = _add(aO, _add(_cross(wd, c), _cross(w, _cross(w, c))))
        F = _scale(m, aC)
        Ic = [[mpf(float(chain.inertia_com[k, a, b])) for b in range(3)] for a in range(3)]
        Iw = _matmul(_matmul(R, Ic), _transpose(R))
        N = _add(_matvec(Iw, wd), _cross(w, _matvec(Iw, w)))
        if O_next is not None:
            n = _add(n, _cross([O_next[i] - O[i] for i in range(3)], f))
        n = _add(n, _add(N, _cross(c, F)))
        f = _add(f, F)
        for jj, e in axes:
            tau[jj] = _dot(e, n)
        O_next = O
    return tau


def dense_reference(chain: Model, q, v, tau=None, dps: int = DEFAULT_DPS) -> list:
    """qdd by an independent dense solve in mpmath (O(n^3), for small chains: tests only).

    ``chain``: a serial chain, revolute axes only (as :func:`newton_euler_mp` takes it).
    GIM column i = newton_euler_mp(q, 0, e_i, no gravity); phi = tau - newton_euler_mp(q, v, 0);
    qdd = mpmath.lu_solve(GIM, phi). Returns a list of mpf.
    """
    n = chain.n_dof
    with mpmath.workdps(dps):
        bias = newton_euler_mp(chain, q, v, np.zeros(n))
        gim = dense_gim_mp(chain, q, dps)
        t = [mpmath.mpf(0)] * n if tau is None else [mpmath.mpf(float(x)) for x in tau]
        rhs = mpmath.matrix([t[i] - bias[i] for i in range(n)])
        x = mpmath.lu_solve(gim, rhs)
        return [x[i] for i in range(n)]


def dense_gim_mp(chain: Model, q, dps: int = DEFAULT_DPS) -> mpmath.matrix:
    """The GIM in mpmath by the independent Newton-Euler (column i = I e_i); small serial
    chains, revolute axes only (as :func:`newton_euler_mp` takes them)."""
    n = chain.n_dof
    with mpmath.workdps(dps):
        zeros = np.zeros(n)
        gim = mpmath.matrix(n, n)
        for i in range(n):
            e = np.zeros(n)
            e[i] = 1.0
            col = newton_euler_mp(chain, q, zeros, e, gravity=False)
            for r in range(n):
                gim[r, i] = col[r]
        return gim
