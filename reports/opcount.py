"""Operation counts of our kernels (Table 7): multiplications/divisions and additions/subtractions.

    python -m redysim.reports.opcount [--out results/opcount]

Counted, not estimated: each kernel's own Python source (``kernel.py_func``, the function numba
compiles, taken by its pass's name from the core's door to the kernels,
:func:`redysim.algorithms.precision.kernel_source`) runs on object arrays of
:class:`Count`, a float that tallies every ``*``, ``/``, ``+`` and ``-`` done on it. Negation,
comparisons and the cos/sin of the joint angles are not counted (the paper's Table 7 has columns for
the four operations only); products with the literal constants a kernel holds (``2.0 * x``) are. The
kernels have no data-dependent branches, so the counts are exact polynomials in n: a*n + b for the
O(n) passes from two sizes, checked on a third; a cubic for the elimination from four sizes, checked
on a fifth.

What is counted, per row:
    RGE-A spatial  ``rge_a_forward_dynamics``: kinematics, Newton-Euler phi, Table A.1's passes
                   (what ``forward_dynamics`` runs for U chains and non-planar R chains);
    RGE-A planar   ``planar_forward_dynamics``: the planar specialisation (R chains in a plane);
    GE-N elimination  ``ge_n`` on a given GIM and phi: the sweep-out and back substitution only
                   (the GIM's O(n^2) assembly and phi are not counted).
And, under ``robots`` (the talk's serial robots, beside its counts in the report's "Robots and
trees" section), on serial robots of R joints about z placed by DH transforms:
    forward dynamics, DH kernel   ``dh_forward_dynamics`` (what ``forward_dynamics`` runs on a
                   robot in DH form: the articulated-body recursion in the DH frames), on robots
                   whose twists are right angles' multiples (0, 90, -90, 180 degrees in turn:
                   the PUMA 560's and the Stanford arm's kind, whose turns about x cost no
                   arithmetic) and on robots of any twists;
    forward dynamics, general     ``rge_a_forward_dynamics``, as above (a general rotation and
                   shift per joint, the tree kernels' PLACED path; ``dh=False``);
    inverse dynamics, DH kernel   ``dh_inverse_dynamics`` (Newton-Euler in the DH frames), the
                   same two kinds of robot;
    inverse dynamics, general     the kinematics pass (with qdd) and ``rnea_backward``.
The general kernels are written for any joint axis and any link frame (full 3 x 3 rotations),
the DH kernels for the four axis-aligned steps of a DH transform (docs/design.md, "DH robots").
Neither counts the check of its result for non-finite numbers (the entries do that), nor the
constants computed once per model that it reads (the general kernels' inertias about the joints;
the DH kernels' table, :func:`redysim.algorithms.dh_form.dh_constants`, whose last row holds
the last body's projected inertia when its joint is revolute: that body's own, a constant).

Output: ``opcount.json`` (the raw counts per size, the fitted polynomials, provenance).
"""

from __future__ import annotations

import argparse
import math
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np

from redysim import Chain, Model, mass_matrix, phi
from redysim.algorithms.dh_form import dh_constants
from redysim.algorithms.precision import kernel_source
from redysim.algorithms.workspace import DH_SCRATCH, bundles_in, kernel_armature
from redysim.harness.provenance import provenance
from redysim.harness.store import write_json_atomic

DEFAULT_OUT = Path("results") / "opcount"
OUT_FILE = "opcount.json"
LINEAR_SIZES = (4, 8, 13)        # links: fit on the first two, check on the third
CUBIC_SIZES = (4, 6, 8, 10, 13)  # DOF of the GIM: fit a cubic on the first four, check the fifth
SEED = 7
# The chains counted: the RE-U steel rod (U) and the section-5 study chain (R); only the shapes of
# the arrays matter to the counts, the values are those of the paper's chains.
U_CHAIN = dict(joint="U", length=0.02, linear_density=7850 * np.pi * 0.05**2, radius=0.05,
               inertia="rod")
R_CHAIN = dict(joint="R", length=1.0, linear_density=7025 * np.pi * 0.02**2, radius=0.02,
               inertia="cylinder")


class Count:
    """A float that counts the arithmetic done on it (class-wide tallies, see :func:`tally`)."""

    __slots__ = ("v",)
    mul = 0  # multiplications and divisions
    add = 0  # additions and subtractions

    def __init__(self, x=0.0):
        self.v = x.v if isinstance(x, Count) else float(x)

    def __float__(self) -> float:
        return self.v

    def __repr__(self) -> str:
        return f"Count({self.v!r})"

    def __add__(self, o):
        Count.add += 1
        return Count(self.v + _value(o))

    def __radd__(self, o):
        Count.add += 1
        return Count(_value(o) + self.v)

    def __sub__(self, o):
        Count.add += 1
        return Count(self.v - _value(o))

    def __rsub__(self, o):
        Count.add += 1
        return Count(_value(o) - self.v)

    def __mul__(self, o):
        Count.mul += 1
        return Count(self.v * _value(o))

    def __rmul__(self, o):
        Count.mul += 1
        return Count(_value(o) * self.v)

    def __truediv__(self, o):
        Count.mul += 1
        return Count(self.v / _value(o))

    def __rtruediv__(self, o):
        Count.mul += 1
        return Count(_value(o) / self.v)

    def __neg__(self):
        return Count(-self.v)

    def __pos__(self):
        return self

    def __abs__(self):
        return Count(abs(self.v))

    def __eq__(self, o):
        return self.v == _value(o)

    def __lt__(self, o):
        return self.v < _value(o)

    def __le__(self, o):
        return self.v <= _value(o)

    def __gt__(self, o):
        return self.v > _value(o)

    def __ge__(self, o):
        return self.v >= _value(o)

    __hash__ = None


def _value(o) -> float:
    return o.v if isinstance(o, Count) else float(o)


def tally(run) -> tuple[int, int]:
    """(multiplications/divisions, additions/subtractions) done by ``run()``."""
    Count.mul = Count.add = 0
    with np.errstate(all="ignore"):
        run()
    return Count.mul, Count.add


def counts(a) -> np.ndarray:
    """``a`` as an object array of :class:`Count`."""
    a = np.asarray(a, dtype=float)
    return np.array([Count(x) for x in a.ravel()], dtype=object).reshape(a.shape)


def empty(*shape) -> np.ndarray:
    return counts(np.zeros(shape))


def make_chain(kind: str, n_links: int) -> Chain:
    p = dict(U_CHAIN if kind == "U" else R_CHAIN)
    return Chain.uniform(n_links, p.pop("joint"), **p)


def state(model: Model) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(SEED)
    return rng.uniform(-0.3, 0.3, model.n_dof), rng.uniform(-0.3, 0.3, model.n_dof)


def count_rge_a_spatial(model: Model) -> tuple[int, int]:
    """One ``rge_a_forward_dynamics`` call (tau = 0), the spatial kernels."""
    c, n = model, model.n_dof
    q, qd = state(c)
    fn = kernel_source("rge-a", Count)
    tree, s = bundles_in(c, counts, lambda shape: empty(*shape))
    args = (tree, counts(q), counts(qd), empty(n), counts(-np.asarray(c.gravity)), empty(n), s,
            empty(n))
    return tally(lambda: fn(*args))


def count_rge_a_planar(chain: Chain) -> tuple[int, int]:
    """One ``planar_forward_dynamics`` call (tau = 0); ``chain``: a planar serial chain (the
    kernel reads its link lengths)."""
    c, n = chain, chain.n_dof
    q, qd = state(c)
    fn = kernel_source("planar", Count)
    args = (counts(c.length), counts(c.mass), counts(c.inertia_O[:, 2, 2]),
            counts(c.mass_com[:, 0]), counts(c.mass_com[:, 1]), counts(kernel_armature(c)),
            counts(c.gravity), counts(q),
            counts(qd), empty(n), empty(n), empty(c.n_links, 12))
    return tally(lambda: fn(*args))


def count_ge_n(model: Model) -> tuple[int, int]:
    """One ``ge_n`` elimination of the model's GIM and phi (assembly not counted)."""
    q, qd = state(model)
    A, b = counts(mass_matrix(model, q)), counts(phi(model, q, qd))
    n = model.n_dof
    fn = kernel_source("ge-n", Count)
    return tally(lambda: fn(A, b, empty(n, n), empty(n)))


# (row label, chain kind, counter, degree of the polynomial in n)
ROWS = (
    ("RGE-A spatial, R joints", "R", count_rge_a_spatial, 1),
    ("RGE-A planar, R joints", "R", count_rge_a_planar, 1),
    ("RGE-A spatial, U joints", "U", count_rge_a_spatial, 1),
    ("GE-N elimination", "R", count_ge_n, 3),
)


def fit(ns: list[int], ys: list[int], degree: int) -> list[Fraction]:
    """The exact polynomial coefficients (highest first) through the first degree + 1 points."""
    pts = list(zip(ns, ys, strict=True))[:degree + 1]
    # Lagrange interpolation in exact rationals
    coef = [Fraction(0)] * (degree + 1)
    for i, (xi, yi) in enumerate(pts):
        basis = [Fraction(1)]
        denom = Fraction(1)
        for j, (xj, _) in enumerate(pts):
            if j == i:
                continue
            basis = [a - xj * b for a, b in zip(basis + [Fraction(0)], [Fraction(0)] + basis,
                                                  strict=True)]
            denom *= xi - xj
        for k, bk in enumerate(basis):
            coef[k] += yi * bk / denom
    return coef


def evaluate(coef: list[Fraction], n: int) -> Fraction:
    out = Fraction(0)
    for c in coef:
        out = out * n + c
    return out


def polynomial_text(coef: list[Fraction]) -> str:
    """``"135*n - 116"``-style text of a polynomial in n (highest power first)."""
    deg = len(coef) - 1
    parts = []
    for k, c in enumerate(coef):
        p = deg - k
        if c == 0:
            continue
        num = str(c) if c.denominator == 1 else f"({c})"
        if p == 0:
            term = num
        else:
            term = ("" if c == 1 else "-" if c == -1 else f"{num}*") + "n" \
                + (f"^{p}" if p > 1 else "")
        parts.append(term)
    text = " + ".join(parts) if parts else "0"
    return text.replace("+ -", "- ").replace("+ (-", "- (")


def dh_robot(n: int, joints: str | None = None, right_angles: bool = False):
    """A serial robot of n joints (R unless ``joints`` gives each: "RRPRRR") from a modified DH
    table with seeded values (:func:`redysim.io.dh.dh_model`): every joint placed by Rx(alpha)
    Tx(a) Rz(theta) Tz(d), so that the general kernels run their PLACED path (a general rotation
    and shift) and the model has the DH form. Only the shapes matter to the counts, and which
    twists are right angles' multiples (``right_angles``: 90, -90, 0, 180 degrees in turn, else
    none is); no length, offset or angle is zero, so no other work is skipped."""
    from redysim.io.dh import DHLink, dh_model

    rng = np.random.default_rng(SEED)
    links = []
    for k in range(n):
        m = rng.uniform(1.0, 5.0)
        alpha = rng.uniform(-1.5, 1.5)
        if right_angles:  # 90, -90, 0 or 180 degrees, in turn
            alpha = (math.pi / 2, -math.pi / 2, 0.0, math.pi)[k % 4]
        links.append(DHLink(a=rng.uniform(0.05, 0.5), alpha=alpha,
                            d=rng.uniform(0.05, 0.5), theta=rng.uniform(-1.5, 1.5),
                            joint=joints[k] if joints else "R", mass=m,
                            com=tuple(rng.uniform(-0.1, 0.1, 3)),
                            inertia=(0.1 * m, 0.12 * m, 0.08 * m)))
    return dh_model(links, convention="modified", name=f"DH{n}")


def count_inverse_dynamics(model) -> tuple[int, int]:
    """One inverse dynamics: the kinematics pass with qdd and Newton-Euler's backward pass."""
    n = model.n_dof
    q, qd = state(model)
    kin, rnea = kernel_source("kinematics", Count), kernel_source("rnea-backward", Count)
    tree, s = bundles_in(model, counts, lambda shape: empty(*shape))
    g = counts(-np.asarray(model.gravity))

    def run():
        kin(tree, counts(q), counts(qd), counts(qd), g, s)
        rnea(tree, s, counts(qd), empty(n))
    return tally(run)


def count_dh(name: str):
    """A counter of the DH kernel ``name`` ("dh-forward" or "dh-inverse", tau or qdd zero)."""
    def counter(model) -> tuple[int, int]:
        n = model.n_dof
        q, qd = state(model)
        fn = kernel_source(name, Count)
        args = (counts(dh_constants(model)), counts(q), counts(qd), empty(n),
                counts(-np.asarray(model.gravity)), empty(n), empty(n, DH_SCRATCH))
        return tally(lambda: fn(*args))
    return counter


ROBOT_ROWS = (  # (row label, what it computes, counter, twists right angles): dh_robot(n), R joints
    ("DH kernel, right-angle twists", "forward", count_dh("dh-forward"), True),
    ("DH kernel, any twists", "forward", count_dh("dh-forward"), False),
    ("general (RGE-A)", "forward", count_rge_a_spatial, False),
    ("DH kernel, right-angle twists", "inverse", count_dh("dh-inverse"), True),
    ("DH kernel, any twists", "inverse", count_dh("dh-inverse"), False),
    ("general (Newton-Euler)", "inverse", count_inverse_dynamics, False),
)


def measure_robots() -> dict:
    """The counts of :data:`ROBOT_ROWS` on DH robots of LINEAR_SIZES joints, fitted a*n + b on
    two sizes and checked on the third."""
    rows, fits = [], []
    for label, kind, counter, right in ROBOT_ROWS:
        label = f"{kind} dynamics, {label}"
        ns, mults, adds = [], [], []
        for n in LINEAR_SIZES:
            m, a = counter(dh_robot(n, right_angles=right))
            ns.append(n)
            mults.append(m)
            adds.append(a)
            rows.append({"algorithm": label, "kind": kind, "n_dof": n, "mult": m, "add": a})
        cm, ca = fit(ns, mults, 1), fit(ns, adds, 1)
        exact = evaluate(cm, ns[2]) == mults[2] and evaluate(ca, ns[2]) == adds[2]
        fits.append({"algorithm": label, "kind": kind,
                     "mult": polynomial_text(cm), "add": polynomial_text(ca),
                     "mult_coef": [float(c) for c in cm], "add_coef": [float(c) for c in ca],
                     "checked_at_dof": ns[2:], "exact": bool(exact)})
    return {"rows": rows, "fits": fits}


def measure() -> dict:
    """The counts of every row of :data:`ROWS` at its sizes, and the fitted polynomials."""
    rows, fits = [], []
    for label, kind, counter, degree in ROWS:
        sizes = LINEAR_SIZES if degree == 1 else CUBIC_SIZES
        chains = [make_chain(kind, s) for s in sizes]  # R chains: links = DOF
        ns, mults, adds = [], [], []
        for ch in chains:
            m, a = counter(ch)
            ns.append(ch.n_dof)
            mults.append(m)
            adds.append(a)
            rows.append({"algorithm": label, "chain": kind, "n_links": ch.n_links,
                         "n_dof": ch.n_dof, "mult": m, "add": a})
        cm, ca = fit(ns, mults, degree), fit(ns, adds, degree)
        check = ns[degree + 1:]
        exact = all(evaluate(cm, n) == y for n, y in zip(check, mults[degree + 1:], strict=True)) \
            and all(evaluate(ca, n) == y for n, y in zip(check, adds[degree + 1:], strict=True))
        fits.append({"algorithm": label, "chain": kind, "degree": degree,
                     "mult": polynomial_text(cm), "add": polynomial_text(ca),
                     "mult_coef": [float(c) for c in cm], "add_coef": [float(c) for c in ca],
                     "checked_at_dof": check, "exact": bool(exact)})
    return {"rows": rows, "fits": fits}


def run(out: Path) -> dict:
    """Count and write ``opcount.json`` into ``out``; returns the counts and fits."""
    res = measure()
    res["robots"] = measure_robots()
    write_json_atomic({"provenance": provenance(), **res}, out / OUT_FILE)
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output directory")
    args = ap.parse_args(argv)
    res = run(args.out)
    for f in res["fits"] + res["robots"]["fits"]:
        print(f"{f['algorithm']:32} mult/div {f['mult']:>28}   add/sub {f['add']:>28}   "
              f"{'exact' if f['exact'] else 'NOT exact'} at DOF {f['checked_at_dof']}")
    print(f"written to {args.out / OUT_FILE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
