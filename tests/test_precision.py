"""Reduced and IEEE precision (section 5): Tables 10, 11, A.2 and 8 from the kernels' own source.

Tier 1 against paper/published.toml, plus the checks that make the numbers trustworthy: the
rounding number type itself, the same source run at 50 decimal places equals the float64 kernel,
and a float32 run never leaves float32.

Findings pinned here (see redysim/algorithms/precision.py and the report
``reports/precision_tables.py``):
- "accuracy 1e-k" is k decimal places, rounded the MATLAB way, round(x / 1e-k) * 1e-k on IEEE
  doubles: all 36 GE-N/RGE-N values of Table 10 and all of Table A.2. Exact decimal arithmetic
  differs at one exact tie (2.50 * 11.77 = 29.425, RGE-N at 1e-2).
- RGE-A reproduces only the 1e-1 row and two more values (documented set below).
- Table 11's GE-N qdd_1 column reproduces at 1e-6, not at the 1e-7 of its caption.
"""

from __future__ import annotations

import math
import types

import numpy as np
import pytest

from redysim import (
    Chain,
    eliminate,
    forward_dynamics,
    load_case,
    load_published,
    mass_matrix,
    phi,
    udu_factors,
)
from redysim.algorithms.precision import (
    PASSES,
    Rounded,
    ieee_qdd,
    kernel_pass,
    kernel_source,
    rebind,
    reduced_factors,
    reduced_qdd,
    rounded_type,
)
from redysim.algorithms.workspace import bundles_in
from redysim.reports.precision_tables import (
    printed_decimals,
    sig_decimals,
    table9_horizontal,
    verdict,
)

PUB = load_published()
T10 = PUB["table10"]["rows"]
KEY = {"GE-N": "ge-n", "RGE-N": "rge-n", "RGE-A": "rge-a"}


def decimals_of(accuracy: float) -> int:
    return round(-math.log10(accuracy))


@pytest.fixture(scope="module")
def table9():
    case = load_case("STUDY-R3-TABLE9")
    return case, forward_dynamics(case.chain, case.q0, case.v0)


def row_verdicts(case, q64, row, arithmetic="double"):
    """Per component: (qdd verdict, dq verdict) at the paper's printed digits."""
    x = reduced_qdd(case.chain, case.q0, case.v0, KEY[row["method"]],
                    decimals_of(row["accuracy"]), arithmetic=arithmetic)
    with np.errstate(all="ignore"):
        dq = (x - q64) / q64 * 100
    return [(verdict(x[i], row["qdd"][i], 4)[0],
             verdict(dq[i], row["dq"][i], printed_decimals(row["dq"][i], 4))[0])
            for i in range(3)], x


# --------------------------------------------------------------------------- the number type
@pytest.mark.parametrize("arithmetic", ["double", "decimal"])
def test_rounding_is_absolute_half_away_from_zero(arithmetic):
    R = rounded_type(2, arithmetic)
    # "double" is MATLAB's round(x / 1e-2) * 1e-2: 12346 * 0.01 = 123.46000000000001, one ulp
    # off the nearest double; "decimal" is exact
    v = lambda x: pytest.approx(x, rel=2 * np.finfo(float).eps, abs=0)  # noqa: E731
    assert float(R(1.005)) in (v(1.0), v(1.01))  # 1.005 is 1.00499999999999989... in binary
    assert float(R(0.125)) == v(0.13) and float(R(-0.125)) == v(-0.13)  # halves away from 0
    assert float(R(123.456)) == v(123.46)  # absolute quantum, not significant digits
    assert float(R(0.004)) == 0.0
    x = R(1.0) / 3.0  # floats on either side, rounded on entry and after the operation
    assert float(x) == v(0.33) and float(3.0 * x) == v(0.99) and float(1 - x) == v(0.67)
    assert math.isinf(float(R(1.0) / R(0.0))) and float(R(-1.0) / 0.0) < 0
    assert math.isnan(float(R(0.0) / R(0.0)))
    assert math.isnan(float(R(1.0) / 0.0 - R(1.0) / 0.0))
    with pytest.raises(TypeError):
        R(1.0) + rounded_type(3, arithmetic)(1.0)


def test_the_tie_that_separates_the_arithmetics():
    """2.50 * 11.77 = 29.425 exactly in decimal (rounds up); 29.424999999999997 in double, which
    MATLAB's round(x / 1e-2) * 1e-2 rounds down. The paper's RGE-N at 1e-2 went down."""
    assert float(rounded_type(2, "decimal")(2.5) * 11.77) == 29.43
    assert float(rounded_type(2, "double")(2.5) * 11.77) == 29.42
    assert issubclass(rounded_type(2), Rounded) and rounded_type(2).arithmetic == "double"


# --------------------------------------------------------------------------- one source
def test_same_source_at_50_places_equals_the_float64_kernel(table9):
    case, q64 = table9
    for method in ("ge-n", "rge-n", "rge-a"):
        x = reduced_qdd(case.chain, case.q0, case.v0, method, 50, arithmetic="decimal")
        assert np.allclose(x, q64, rtol=1e-12, atol=0), method
    f = reduced_factors(case.chain, case.q0, case.v0, "ge-n", 50, arithmetic="decimal")
    e = eliminate(mass_matrix(case.chain, case.q0), phi(case.chain, case.q0, case.v0), "ge-n")
    np.testing.assert_allclose(f.U, e.factor, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(f.L, e.multipliers, rtol=1e-12, atol=1e-12)


def test_spatial_source_at_50_places_equals_the_float64_kernel():
    chain = Chain.uniform(3, "U", length=0.5, mass=1.5, radius=0.05, inertia="cylinder")
    rng = np.random.default_rng(7)
    q, qd = rng.normal(size=chain.n_dof), rng.normal(size=chain.n_dof)
    ref = forward_dynamics(chain, q, qd)
    for method in ("ge-n", "rge-n", "rge-a"):
        x = reduced_qdd(chain, q, qd, method, 50, arithmetic="decimal")
        assert np.allclose(x, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max()), method
    fused = reduced_qdd(chain, q, qd, "rge-a", 50, arithmetic="decimal", fused_phi=True)
    assert np.allclose(fused, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    f = reduced_factors(chain, q, qd, "rge-a", 50, arithmetic="decimal")
    U, D = udu_factors(chain, q)
    np.testing.assert_allclose(f.U, U, atol=1e-12)
    np.testing.assert_allclose(f.D, D, atol=1e-12)


def test_float64_source_equals_the_compiled_kernel():
    case = load_case("STUDY-R10")
    q = np.linspace(-0.5, 0.7, 10)
    qd = np.linspace(1.0, -1.0, 10)
    for method in ("ge-n", "rge-n", "rge-a"):
        ref = forward_dynamics(case.chain, q, qd, method=method)
        x = ieee_qdd(case.chain, q, qd, method, np.float64)
        np.testing.assert_allclose(x, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())


def _objects(a, t):
    a = np.asarray(a, dtype=float)
    out = np.empty(a.shape, dtype=object)
    for i in np.ndindex(a.shape):
        out[i] = t(a[i])
    return out


def _kinds(*arrays):
    """Types of every value written, exact Python-float constants named by value."""
    return {type(v).__name__ if type(v) is not float else float(v) for a in arrays for v in a.flat}


def test_float32_runs_stay_in_float32():
    """Run with object arrays of np.float32: a float64 intermediate would be written as one. Only
    the exact constants 0.0 and 1.0 may appear as Python floats."""
    t = np.float32
    ok = {"float32", 0.0, 1.0}
    case = load_case("STUDY-R5")
    ch, n = case.chain, case.chain.n_dof
    q, qd = np.array([0.3, -0.2, 0.5, 0.1, -0.4]), np.array([0.5, -1.0, 0.2, 0.3, 0.1])
    for name in ("ge-n", "rge-n"):
        A, b = _objects(mass_matrix(ch, q), t), _objects(phi(ch, q, qd), t)
        mult, x = _objects(np.zeros((n, n)), t), _objects(np.zeros(n), t)
        kernel_source(name, t)(A, b, mult, x)
        assert _kinds(A, b, mult, x) <= ok
    qdd, scratch = _objects(np.zeros(n), t), _objects(np.zeros((n, 12)), t)
    kernel_source("planar", t)(
        *(_objects(a, t) for a in (ch.length, ch.mass, ch.inertia_O[:, 2, 2], ch.mass_com[:, 0],
                                   ch.mass_com[:, 1], ch.armature[:0], ch.gravity, q, qd,
                                   np.zeros(n))),
        qdd, scratch)
    assert _kinds(qdd, scratch) <= ok
    ch = Chain.uniform(4, "U", length=0.5, mass=1.5, radius=0.05, inertia="cylinder")
    n = ch.n_dof
    rng = np.random.default_rng(3)
    q, qd = rng.normal(size=n), rng.normal(size=n)
    tree, s = bundles_in(ch, lambda a: _objects(a, t), lambda shape: _objects(np.zeros(shape), t))
    qdd = _objects(np.zeros(n), t)
    kernel_source("rge-a", t)(
        tree, _objects(q, t), _objects(qd, t), _objects(np.zeros(n), t),
        _objects(-ch.gravity, t), _objects(np.zeros(n), t), s, qdd)
    assert _kinds(qdd, *s) <= ok
    ref = forward_dynamics(ch, q, qd)
    assert np.abs(qdd.astype(float) - ref).max() < 1e-4 * np.abs(ref).max()


def test_the_door_gives_each_pass_compiled_and_as_its_python_source():
    """Every name of PASSES (the door for code outside the core) is a compiled kernel; its rebound
    Python source is the same code with its own ``math``, cached per arithmetic. The methods'
    names are passes (the runners above call them so); an unknown name is refused, naming them."""
    assert {"ge-n", "rge-n", "rge-a"} <= set(PASSES)
    codes = set()
    for name in PASSES:
        compiled = kernel_pass(name)
        source = kernel_source(name, np.float32)
        assert source.__code__ is compiled.py_func.__code__, name
        assert source is kernel_source(name, np.float32), name
        assert source.__globals__["math"].cos(0.5) == np.float32(math.cos(0.5)), name
        trig = types.SimpleNamespace(cos=math.cos, sin=math.sin)
        assert rebind(name, ("door test", name), trig).__globals__["math"] is trig, name
        codes.add(source.__code__)
    assert len(codes) == len(PASSES), "two names for one kernel"
    with pytest.raises(ValueError, match="choose one of kinematics, rnea-backward"):
        kernel_pass("rnea")


def test_ieee_errors_follow_conditioning():
    """float32 on the 20-link study chain (cond2 6.7e5, u cond2 0.04): the O(n^3) eliminations
    lose ~1e-3, RGE-A ~1e-4; float16 overflows once phi exceeds 65504 (40 links)."""
    case = load_case("STUDY-R20")
    ref = np.linalg.solve(mass_matrix(case.chain, case.q0), phi(case.chain, case.q0, case.v0))
    err = {m: np.linalg.norm(ieee_qdd(case.chain, case.q0, case.v0, m, np.float32) - ref)
           / np.linalg.norm(ref) for m in ("ge-n", "rge-n", "rge-a")}
    assert all(1e-6 < e < 0.04 for e in err.values()), err
    assert err["rge-a"] < err["ge-n"] / 10 and err["rge-a"] < err["rge-n"] / 10, err
    assert ieee_qdd(case.chain, case.q0, case.v0, "rge-a", np.float32).dtype == np.float32
    big = load_case("STUDY-R40")
    x = ieee_qdd(big.chain, big.q0, big.v0, "rge-n", np.float16)
    assert not np.all(np.isfinite(x))


# --------------------------------------------------------------------------- Table 10
def expected_verdicts(row) -> list[tuple[str, str]]:
    """Every value exact, but at 1e-1 GE-N's U33 rounds to exactly 0: qdd NaN, Inf, -Inf where
    the paper prints NaN, Inf, Inf (its dq: NaN, Inf, Inf): qdd_3 an infinity of the other
    sign, a verdict of its own ('sign'), never a silent match."""
    if row["method"] == "GE-N" and row["accuracy"] == 1e-1:
        return [("exact", "exact"), ("exact", "exact"), ("sign", "exact")]
    return [("exact", "exact")] * 3


@pytest.mark.parametrize("method", ["GE-N", "RGE-N"])
def test_table10_all_18_values(table9, method):
    """qdd to its 4 printed decimals and dq (% deviation) to its printed digits, every accuracy
    (expected_verdicts)."""
    case, q64 = table9
    for row in (r for r in T10 if r["method"] == method):
        v, x = row_verdicts(case, q64, row)
        assert v == expected_verdicts(row), (row, x, v)


def test_table10_horizontal_state_gives_the_same(table9):
    """q = 0 with g = 4.905 (the paper's stated configuration) gives Table 9's GIM and phi too."""
    _, q64 = table9
    case = table9_horizontal()
    for row in (r for r in T10 if r["method"] != "RGE-A"):
        v, x = row_verdicts(case, q64, row)
        assert v == expected_verdicts(row), (row, x, v)


def test_table10_decimal_arithmetic_misses_one_row(table9):
    """Exact decimal arithmetic: everything but RGE-N at 1e-2, where the tie 29.425 rounds up."""
    case, q64 = table9
    for row in (r for r in T10 if r["method"] != "RGE-A"):
        v, x = row_verdicts(case, q64, row, arithmetic="decimal")
        if row["method"] == "RGE-N" and row["accuracy"] == 1e-2:
            np.testing.assert_array_equal(x, [-6.25, 7.99, -2.35])
            assert all(a == "differs" for a, _ in v)
        else:
            assert v == expected_verdicts(row), (row, x, v)


# RGE-A: (accuracy, component) whose qdd AND dq reproduce with the main rule (horizontal state,
# the rounded double phi passed in, planar kernel). The paper's RGE-A (ReDySim's MATLAB, source
# not public) rounds at other points; see the report for the values and the variants tried.
RGE_A_REPRODUCED = {(0.1, 1), (0.1, 2), (0.1, 3), (0.001, 1), (1e-6, 1)}


def test_table10_rge_a_what_reproduces(table9):
    _, q64 = table9
    case = table9_horizontal()
    got = set()
    for row in (r for r in T10 if r["method"] == "RGE-A"):
        v, _ = row_verdicts(case, q64, row)
        # "sign": dq equal in magnitude; published.toml marks Table 10's signs as re-derived
        got |= {(row["accuracy"], i + 1) for i, (a, b) in enumerate(v)
                if a == "exact" and b in ("exact", "sign")}
    assert got == RGE_A_REPRODUCED


# --------------------------------------------------------------------------- Table A.2
@pytest.mark.parametrize("name,method", [("ge", "ge-n"), ("rge", "rge-n")])
def test_tableA2_rounded_factors(table9, name, method):
    """The published factors, cond2 and phi-hat are those of the 1e-3 ROUNDED elimination: every
    entry to its printed digits (RGE's cond2(U') = 21.467 printed truncated as 21.46)."""
    case, _ = table9
    f = reduced_factors(case.chain, case.q0, case.v0, method, 3)
    pub = PUB["tableA2"][name]
    ours = {"L": f.L, "U": f.U, "phi_hat": f.phihat,
            "cond2_L": np.linalg.cond(f.L), "cond2_U": np.linalg.cond(f.U)}
    for key, value in ours.items():
        paper = np.ravel(np.array(pub[key], dtype=float))
        for o, p in zip(np.ravel(value), paper, strict=True):
            v, _ = verdict(o, p, printed_decimals(p))
            assert v == "exact" or (v == "truncation" and key.startswith("cond2")), (key, o, p)
    # ... and not those of the exact factors
    e = eliminate(mass_matrix(case.chain, case.q0), phi(case.chain, case.q0, case.v0), method)
    exact = {"cond2_L": e.multipliers if method == "ge-n" else e.factor,
             "cond2_U": e.factor if method == "ge-n" else e.multipliers}
    for key, factor in exact.items():
        assert verdict(np.linalg.cond(factor), pub[key], 2)[0] == "differs", key


# --------------------------------------------------------------------------- Table 11
T11 = {r["links"]: r for r in PUB["table11"]["rows"]}


def table11_error(n, method, decimals, i):
    """The paper's Table 11 convention: (qdd - qdd_F) / qdd * 100 against the double solution."""
    case = load_case(f"STUDY-R{n}")
    q64 = np.linalg.solve(mass_matrix(case.chain, case.q0),
                          phi(case.chain, case.q0, case.v0))
    x = reduced_qdd(case.chain, case.q0, case.v0, method, decimals)
    return (q64[i] - x[i]) / q64[i] * 100, abs(q64[i])


@pytest.mark.parametrize("n", [5, 10, 20, 40, 60])
def test_table11_ge_n_qdd1_reproduces_at_1e6(n):
    """GE-N's qdd_1 column: within 2 quanta of 1e-6 at 5-40 links and to the printed 5 significant
    digits from 40 links on (80 and 100 too: see the report). The caption's 1e-7 does not fit."""
    e, q1 = table11_error(n, "ge-n", 6, 0)
    paper = T11[n]["ge_sweep_qdd1"]
    if n >= 40:
        assert verdict(e, paper, sig_decimals(paper))[0] == "exact", (e, paper)
    if n <= 40:
        assert abs(e - paper) / 100 * q1 <= 2.05e-6, (e, paper)
    if n >= 20:
        e7, _ = table11_error(n, "ge-n", 7, 0)
        assert abs(e7 - paper) > 0.5 * abs(paper), (e7, paper)


@pytest.mark.parametrize("n", [5, 10, 20, 40])
def test_table11_rge_a_qdd1_within_a_few_quanta_at_1e6(n):
    """RGE-A's qdd_1 column (-12.435852 in the paper for every n >= 10): exact at 10 links, within
    4 quanta of 1e-6 elsewhere; the paper's RGE-A rounds at other points (see Table 10)."""
    e, q1 = table11_error(n, "rge-a", 6, 0)
    paper = T11[n]["rge_subst_qdd1"]
    assert abs(e - paper) / 100 * q1 <= 4.05e-6, (e, paper)
    if n == 10:
        assert verdict(e, paper, sig_decimals(paper))[0] == "exact"


# --------------------------------------------------------------------------- Table 8
def _ode45_steps(name: str, method: str, decimals: int, ulps: int = 0) -> int:
    """ode45 steps (rtol 1e-4, atol 1e-6) on the case with the method's reduced-precision qdd;
    ``ulps``: q0 moved by that many units in the last place of max(|q0|, 1), a last-bit change
    of the start such as another CPU's arithmetic would make."""
    integrate = pytest.importorskip("redysim.integrators.explicit")
    case = load_case(name)
    ch, n = case.chain, case.chain.n_dof

    def rhs(_t, y):
        return np.concatenate([y[n:], reduced_qdd(ch, y[:n], y[n:], KEY[method], decimals)])

    y0 = np.concatenate([case.q0, case.v0])
    y0[:n] += ulps * np.spacing(np.maximum(np.abs(y0[:n]), 1.0))
    sol = integrate.integrate(rhs, (0.0, case.t_end), y0, "ode45", rtol=1e-4, atol=1e-6,
                              t_eval=integrate.sample_times(0.0, case.t_end, 0.05))
    assert sol.status == 0, sol.message
    return sol.steps


# Starts moved by k = 0, +-1, +-2 ulps: GE-N's count is chaotic in the last bits.
GE_N_STARTS = (0, 1, -1, 2, -2)


def test_table8_three_link_steps():
    """ode45 on the 3-link chain for 5 s at 1e-3: GE-N needs ~2.5x the steps of RGE-N and RGE-A
    (paper: 618 vs 231 and 134).

    GE-N's count is chaotic: measured here (2026-11-23) from 40 starts moved by 0..39 ulps it
    took 603 to 656 steps (median 629), and before the integrator's stage sums left BLAS it took
    630, 636 or 650 from the same start depending only on OpenBLAS's kernel (Prescott,
    Haswell, SkylakeX). RGE-N took 179 or 185 and RGE-A 244 from every one of those starts. So
    this asserts the median of five starts: within 10 % of the paper's 618 (the single-start
    spread is -2.4 %..+6.1 % of it), and at least 2.3x RGE-N's and RGE-A's (ours: 2.58x; the
    report's sensitivity rows show the rest)."""
    rows = {r["method"]: r for r in PUB["table8"]["three_link"]["rows"]}
    ge_n = sorted(_ode45_steps("STUDY-R3", "GE-N", 3, ulps=k) for k in GE_N_STARTS)
    median = ge_n[len(ge_n) // 2]
    others = {m: _ode45_steps("STUDY-R3", m, 3) for m in ("RGE-N", "RGE-A")}
    assert abs(median - rows["GE-N"]["steps"]) <= 0.10 * rows["GE-N"]["steps"], ge_n
    assert median > 2.3 * max(others.values()), (ge_n, others)


@pytest.mark.parametrize("method", ["RGE-N", "RGE-A"])
def test_table8_ten_link_steps(method):
    """10 links, 3 s at 1e-5: RGE-N and RGE-A within 5 % of the paper's 196 and 177 steps (GE-N,
    4723 in the paper, 4780 here, takes a minute: see the report). Not chaotic like the 3-link
    GE-N count: from 10 starts moved by 0..9 ulps, RGE-N took 190-193 steps and RGE-A 180-182
    (measured here, 2026-11-23)."""
    paper = next(r for r in PUB["table8"]["ten_link"]["rows"] if r["method"] == method)
    steps = _ode45_steps("STUDY-R10", method, 5)
    assert abs(steps - paper["steps"]) <= 0.05 * paper["steps"], steps
