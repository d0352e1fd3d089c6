"""Tier 2: identities on seeded random chains of every joint type and mixes, 1..200 links.

Each identity compares two different computations (or a computation with a finite difference), so
an error in one of them shows.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import (
    ALL_JOINT_MIXES,
    EPS,
    denoc_gim,
    random_chain,
    random_state,
    rel,
    stable_seed,
)

from redysim import (
    Chain,
    Joint,
    Link,
    Workspace,
    energy,
    forward_dynamics,
    generalized_momentum,
    inverse_dynamics,
    mass_matrix,
    phi,
    tip,
    udu_factors,
)

SIZES = [1, 2, 3, 10, 50, 200]
SPREADS = ["wide", "straight"]
MIX_IDS = ["R", "U", "S", "P", "mixed"]


def cases():
    for mix, mid in zip(ALL_JOINT_MIXES, MIX_IDS, strict=True):
        for n in SIZES:
            for spread in SPREADS:
                yield pytest.param(mix, n, spread, id=f"{mid}-{n}-{spread}")


@pytest.mark.parametrize("mix,n_links,spread", list(cases()))
def test_rge_a_solves_the_gim(mix, n_links, spread):
    """RGE-A qdd = solve(GIM, phi): to 1e-10 where cond2 < 1e5, else within 10 cond2 eps (the
    dense solve itself is only that good)."""
    rng = np.random.default_rng(stable_seed(mix, n_links, spread))
    chain = random_chain(rng, n_links, mix)
    q, qd, tau = random_state(rng, chain, spread)
    gim = mass_matrix(chain, q)
    ref = np.linalg.solve(gim, phi(chain, q, qd, tau))
    qdd = forward_dynamics(chain, q, qd, tau)
    cond = np.linalg.cond(gim)
    tol = 1e-10 if cond < 1e5 else 10 * cond * EPS
    err = np.linalg.norm(qdd - ref) / np.linalg.norm(ref)
    assert err < tol, f"relative error {err:.3g}, cond2 {cond:.3g}, tolerance {tol:.3g}"


@pytest.mark.parametrize("mix", ALL_JOINT_MIXES, ids=MIX_IDS)
def test_rge_a_principal_axes_path_solves_the_gim(mix, rng):
    """Links whose principal axes are the link frame's (COM on the x axis, diagonal inertia, as
    rod and cylinder links are) have I_O diagonal, and RGE-A forms their R I_O R^T by a shorter
    path; the random chains above take the general one. Three different moments per link, so a
    term on the wrong axis shows; the GIM is built by composite masses (the general product)."""
    links = []
    for _ in range(30):
        length, mass = rng.uniform(0.1, 1.0), rng.uniform(0.5, 5.0)
        box = rng.uniform(0.05, 1.0, 3) * length  # a box's moments: three different ones
        moments = mass / 12 * np.array([box[1] ** 2 + box[2] ** 2, box[0] ** 2 + box[2] ** 2,
                                        box[0] ** 2 + box[1] ** 2])
        links.append(Link(length, mass, (rng.uniform(0.2, 0.8) * length, 0.0, 0.0),
                          tuple(map(tuple, np.diag(moments)))))
    joints = [mix[k % len(mix)] for k in range(len(links))]
    chain = Chain.build(links, joints)
    assert not (chain.inertia_O - chain.inertia_O * np.eye(3)).any()  # the path under test
    q, qd, tau = random_state(rng, chain, "wide")
    gim = mass_matrix(chain, q)
    ref = np.linalg.solve(gim, phi(chain, q, qd, tau))
    cond = np.linalg.cond(gim)
    # planar=False: the all-R chain would otherwise run the planar kernel, not this path
    qdd = forward_dynamics(chain, q, qd, tau, planar=False)
    assert rel(qdd, ref) < max(1e-10, 10 * cond * EPS)


@pytest.mark.parametrize("mix,n_links,spread", list(cases()))
def test_inverse_of_forward_returns_tau(mix, n_links, spread):
    rng = np.random.default_rng(stable_seed(mix, n_links, spread, 1))
    chain = random_chain(rng, n_links, mix)
    q, qd, tau = random_state(rng, chain, spread)
    qdd = forward_dynamics(chain, q, qd, tau)
    tau_back = inverse_dynamics(chain, q, qd, qdd)
    # relative to the size of the terms that cancel in tau = I qdd + C qd + g
    scale = np.abs(mass_matrix(chain, q)).max() * np.abs(qdd).max() + np.abs(tau).max()
    assert np.abs(tau_back - tau).max() / scale < 1e-9


@pytest.mark.parametrize("mix", ALL_JOINT_MIXES, ids=MIX_IDS)
@pytest.mark.parametrize("n_links", [1, 2, 7, 40])
def test_composite_gim_equals_denoc_assembly(mix, n_links, rng):
    """Eq. 10a (composite masses) equals N_d^T N_l^T M N_l N_d built explicitly (Eq. 7-10a)."""
    chain = random_chain(rng, n_links, mix)
    q, _, _ = random_state(rng, chain)
    assert rel(mass_matrix(chain, q), denoc_gim(chain, q)) < 1e-12


@pytest.mark.parametrize("mix", ALL_JOINT_MIXES, ids=MIX_IDS)
@pytest.mark.parametrize("n_links", [1, 2, 10, 100])
def test_udu_factors(mix, n_links, rng):
    chain = random_chain(rng, n_links, mix)
    q, _, _ = random_state(rng, chain)
    U, D = udu_factors(chain, q)
    gim = mass_matrix(chain, q)
    assert np.array_equal(np.tril(U, -1), np.zeros_like(U))
    assert np.array_equal(np.diag(U), np.ones(chain.n_dof))
    assert np.array_equal(D, np.diag(np.diag(D))) and np.all(np.diag(D) > 0)
    assert rel(U @ D @ U.T, gim) < 1e-12


@pytest.mark.parametrize("mix", ALL_JOINT_MIXES, ids=MIX_IDS)
def test_power_balance(mix, rng):
    """dE/dt = qd . tau along the motion, by a central difference in time.

    The path q(t + s) = q + s qd + s^2/2 qdd is a polynomial in s, so the central difference has
    an even-power error expansion; one Richardson step cancels its h^2 term (random fast states
    make that term ~1e-5 relative at h = 1e-5)."""
    chain = random_chain(rng, 12, mix)
    q, qd, tau = random_state(rng, chain)
    qdd = forward_dynamics(chain, q, qd, tau)

    def central(h):
        E = [sum(energy(chain, q + s * h * qd + 0.5 * h * h * qdd, qd + s * h * qdd))
             for s in (-1.0, 1.0)]
        return (E[1] - E[0]) / (2 * h)

    h = 1e-4
    dEdt = (4 * central(h / 2) - central(h)) / 3
    power = qd @ tau
    scale = abs(qd) @ abs(tau) + abs(qd) @ abs(phi(chain, q, qd))
    assert abs(dEdt - power) / scale < 1e-7, (dEdt, power)


@pytest.mark.parametrize("mix", ALL_JOINT_MIXES, ids=MIX_IDS)
def test_kinetic_energy_is_the_gim_quadratic_form(mix, rng):
    chain = random_chain(rng, 30, mix)
    q, qd, _ = random_state(rng, chain)
    T, _ = energy(chain, q, qd)
    assert abs(T - 0.5 * qd @ mass_matrix(chain, q) @ qd) / T < 1e-12


@pytest.mark.parametrize("mix", ALL_JOINT_MIXES, ids=MIX_IDS)
def test_gravity_terms_are_the_gradient_of_V(mix, rng):
    """phi(q, 0, 0) = -dV/dq (central differences)."""
    chain = random_chain(rng, 8, mix)
    q, _, _ = random_state(rng, chain)
    zero = np.zeros(chain.n_dof)
    g = -phi(chain, q, zero)
    h = 1e-6
    grad = np.empty(chain.n_dof)
    for i in range(chain.n_dof):
        dq = np.zeros(chain.n_dof)
        dq[i] = h
        grad[i] = (energy(chain, q + dq, zero)[1] - energy(chain, q - dq, zero)[1]) / (2 * h)
    assert rel(grad, g) < 1e-7


@pytest.mark.parametrize("mix", ALL_JOINT_MIXES, ids=MIX_IDS)
def test_gim_is_the_hessian_of_T(mix, rng):
    """I(q) = d^2 T / d qd^2, by central differences of T in qd (T is quadratic: exact)."""
    chain = random_chain(rng, 5, mix)
    q, qd, _ = random_state(rng, chain)
    n, h = chain.n_dof, 1e-3
    H = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            ei, ej = np.eye(n)[i] * h, np.eye(n)[j] * h
            T = [energy(chain, q, qd + si * ei + sj * ej)[0] for si, sj in
                 ((1, 1), (1, -1), (-1, 1), (-1, -1))]
            H[i, j] = (T[0] - T[1] - T[2] + T[3]) / (4 * h * h)
    assert rel(H, mass_matrix(chain, q)) < 1e-8


@pytest.mark.parametrize("mix", ALL_JOINT_MIXES, ids=MIX_IDS)
def test_generalized_momentum_is_the_gim_times_qd(mix, rng):
    """p = I(q) qd by one backward pass of body momenta, against the composite-mass GIM."""
    chain = random_chain(rng, 30, mix)
    q, qd, _ = random_state(rng, chain)
    p = generalized_momentum(chain, q, qd)
    assert rel(p, mass_matrix(chain, q) @ qd) < 1e-12


@pytest.mark.parametrize("mix", ALL_JOINT_MIXES, ids=MIX_IDS)
def test_lagrangian_gradient_by_central_differences(mix, rng):
    """dL/dq at fixed qd (the momentum kernel's turn of each axis, and the gravity terms)
    against central differences of T - V, one Richardson step."""
    chain = random_chain(rng, 8, mix)
    q, qd, _ = random_state(rng, chain)
    _, grad = generalized_momentum(chain, q, qd, gradient=True)
    n = chain.n_dof

    def central(i, h):
        dq = np.zeros(n)
        dq[i] = h
        L = [(lambda T, V: T - V)(*energy(chain, q + s * dq, qd)) for s in (-1.0, 1.0)]
        return (L[1] - L[0]) / (2 * h)

    fd = np.array([(4 * central(i, 5e-5) - central(i, 1e-4)) / 3 for i in range(n)])
    assert rel(grad, fd) < 1e-9


@pytest.mark.parametrize("mix", ALL_JOINT_MIXES, ids=MIX_IDS)
def test_momentum_balance(mix, rng):
    """dp/dt = dL/dq + tau along the motion that forward dynamics gives (Lagrange's equations
    in momentum form: ties RGE-A's qdd to two passes that never solve anything), by a central
    difference in time with one Richardson step, as test_power_balance. The step follows the
    motion's own time scale: a random S chain near gimbal lock reaches |qdd| ~ 1e6, where a
    fixed 1e-4 leaves an h^4 error of 1e-2."""
    chain = random_chain(rng, 12, mix)
    q, qd, tau = random_state(rng, chain)
    qdd = forward_dynamics(chain, q, qd, tau)

    def central(h):
        p = [generalized_momentum(chain, q + s * h * qd + 0.5 * h * h * qdd, qd + s * h * qdd)
             for s in (-1.0, 1.0)]
        return (p[1] - p[0]) / (2 * h)

    h = 1e-3 / (1.0 + np.abs(qd).max() + np.sqrt(np.abs(qdd).max()))
    dpdt = (4 * central(h / 2) - central(h)) / 3
    _, grad = generalized_momentum(chain, q, qd, gradient=True)
    assert rel(dpdt, grad + tau) < 1e-9


@pytest.mark.parametrize("method", ["ge-n", "rge-n"])
@pytest.mark.parametrize("mix", ALL_JOINT_MIXES, ids=MIX_IDS)
def test_numerical_eliminations_solve_the_gim(method, mix, rng):
    chain = random_chain(rng, 6, mix)
    q, qd, tau = random_state(rng, chain, "straight")
    ref = np.linalg.solve(mass_matrix(chain, q), phi(chain, q, qd, tau))
    assert rel(forward_dynamics(chain, q, qd, tau, method=method), ref) < 1e-10


@pytest.mark.parametrize("n_links", [1, 2, 10, 200])
def test_planar_specialisation_equals_spatial(n_links, rng):
    chain = random_chain(rng, n_links, ("R",), general_axes=False)
    chain = type(chain).build(
        [l for l in _links(chain)], ["R"] * n_links, gravity=(0.3, -9.81, 0.0))
    assert chain.is_planar
    q, qd, tau = random_state(rng, chain)
    ws = Workspace(chain)
    planar = forward_dynamics(chain, q, qd, tau, planar=True, ws=ws)
    spatial = forward_dynamics(chain, q, qd, tau, planar=False, ws=ws)
    cond = np.linalg.cond(mass_matrix(chain, q))
    assert rel(planar, spatial) < max(1e-12, 10 * cond * EPS)


def _links(chain):
    from redysim import Link

    for k in range(chain.n_links):
        yield Link(chain.length[k], chain.mass[k], tuple(chain.com[k]),
                   tuple(map(tuple, chain.inertia_com[k])))


def test_workspace_reuse_gives_identical_results(rng):
    chain = random_chain(rng, 20, ("U",))
    ws = Workspace(chain)
    q, qd, tau = random_state(rng, chain)
    a = forward_dynamics(chain, q, qd, tau, ws=ws).copy()
    forward_dynamics(chain, -q, qd, -tau, ws=ws)
    b = forward_dynamics(chain, q, qd, tau, ws=ws)
    assert np.array_equal(a, b)


def test_compiled_sincos_is_within_one_ulp_of_libm():
    """The kinematics' inline sincos (fdlibm's polynomials for |x| <= pi/4, libm beyond) against
    Python's math.cos/math.sin, which call the platform libm: at most 1 ulp apart anywhere."""
    import math

    import numba

    from redysim.algorithms._kernels.joints import sincos

    both = numba.njit(lambda x: sincos(x))
    rng = np.random.default_rng(3)
    far = rng.uniform(math.pi / 4, 50.0, 2_000) * rng.choice([-1.0, 1.0], 2_000)
    x = np.concatenate([rng.uniform(-math.pi / 4, math.pi / 4, 20_000),
                        rng.uniform(-1e-6, 1e-6, 2_000), [0.0, -0.0, math.pi / 4, -math.pi / 4],
                        far])  # beyond pi/4: libm itself
    got = np.array([both(v) for v in x])
    ref = np.array([(math.cos(v), math.sin(v)) for v in x])
    ulp = np.abs(got - ref) / np.spacing(np.abs(ref))
    assert ulp.max() <= 1.0
    assert (got[-2_000:] == ref[-2_000:]).all(), "outside [-pi/4, pi/4] libm is called"
    assert sincos(0.5) == (math.cos(0.5), math.sin(0.5)), "the Python definition is libm's"


def test_chain_arrays_stay_read_only_and_kernels_get_their_owners(rng):
    """The chain's arrays are read-only views; the kernels get the writeable arrays behind them
    (numba types read-only arrays on a slow path), the same memory, never a copy; so too after
    pickling (numpy unpickles arrays writeable), with the same qdd."""
    import pickle

    from redysim.model.parts import kernel_alias

    chain = random_chain(rng, 12, ("U",))
    for name in ("length", "mass", "inertia_O", "mass_com", "dof_u", "joint_qoff"):
        a = getattr(chain, name)
        assert not a.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            a[...] = 0
        owner = kernel_alias(a)
        assert owner.flags.writeable and np.shares_memory(owner, a)
        assert owner.shape == a.shape and owner.dtype == a.dtype
    q, qd, tau = random_state(rng, chain)
    qdd = forward_dynamics(chain, q, qd, tau)
    again = pickle.loads(pickle.dumps(chain))
    assert not again.inertia_O.flags.writeable
    assert np.shares_memory(kernel_alias(again.inertia_O), again.inertia_O)
    assert np.array_equal(forward_dynamics(again, q, qd, tau), qdd)


@pytest.mark.parametrize("name", ["RGE_A", "PLANAR"])
def test_entry_points_declare_the_types_they_call_their_kernels_with(name):
    """An entry point loads its kernels, for the types it calls them with, before itself
    (``redysim._jit.EntryPoint``: an entry loaded from numba's disk cache then runs the kernels'
    own code, not its copies of it, which ran ~3% slower). The declared types must be the ones
    numba infers for the entry's calls, or the kernels loaded first are never called: typed
    afresh here, every call to a kernel in the entry has exactly the declared argument types."""
    import numba

    from redysim._jit import OPTIONS
    from redysim.algorithms._kernels import entry

    point = getattr(entry, name)
    declared = {kernel: tuple(types) for kernel, types in point.callees}
    fresh = numba.njit(point.signature, **{**OPTIONS, "cache": False})(point.func)
    annotation = fresh.overloads[fresh.signatures[0]].type_annotation
    called = {}
    for expr, sig in annotation.calltypes.items():
        if getattr(expr, "op", None) != "call":
            continue
        ty = annotation.typemap.get(expr.func.name)
        if isinstance(ty, numba.types.Dispatcher):
            called[ty.dispatcher] = tuple(sig.args)
    assert called == declared


class _Sub(np.ndarray):
    """A numpy subclass: not the entry point's plain ndarray, so converted first."""


@pytest.mark.parametrize("joints, planar", [(("U",), None), (("R", "U", "S", "P"), None),
                                            ("planar", None), ("planar", False)])
def test_forward_dynamics_gives_one_qdd_for_every_form_of_the_state(rng, joints, planar):
    """Plain float64 vectors go straight to the compiled entry point (its own type and size
    checks); any other form is checked and converted first. Both give the same qdd, with or
    without a workspace and ``out``; and a workspace left by the entry point holds the factors
    udu_factors computes."""
    from redysim import Workspace, udu_factors

    chain = (Chain.uniform(7, "R", mass=1.3, radius=0.02) if joints == "planar"
             else random_chain(rng, 7, joints))
    n = chain.n_dof
    q = rng.integers(-2, 3, n).astype(float)  # integers: the int form is exact
    qd, tau = rng.normal(size=n), rng.normal(size=n)
    ref = forward_dynamics(chain, q, qd, tau, planar=planar)
    assert np.isfinite(ref).all()
    ws, out = Workspace(chain), np.empty(n)
    assert forward_dynamics(chain, q, qd, tau, planar=planar, ws=ws, out=out) is out
    assert np.array_equal(out, ref)

    def forms(x):
        read_only = x.copy()
        read_only.flags.writeable = False
        return {"list": x.tolist(), "tuple": tuple(x), "read-only": read_only,
                "strided": np.repeat(x, 2)[::2], "subclass": x.view(_Sub),
                "big-endian": x.astype(">f8")}

    cases = [(name, (f, qd, tau)) for name, f in forms(q).items()]
    cases += [(f"qd {name}", (q, f, tau)) for name, f in forms(qd).items()]
    cases += [(f"tau {name}", (q, qd, f)) for name, f in forms(tau).items()]
    cases += [("int", (q.astype(np.int64), qd, tau))]
    for name, args in cases:
        for kw in ({}, {"ws": ws, "out": np.empty(n)}):
            assert np.array_equal(forward_dynamics(chain, *args, planar=planar, **kw), ref), name
    # float32 is rounded once, at the door: the float64 qdd of the rounded values
    q32 = qd.astype(np.float32)
    assert np.array_equal(forward_dynamics(chain, q, q32, tau, planar=planar, ws=ws),
                          forward_dynamics(chain, q, q32.astype(float), tau, planar=planar))
    if not (planar is None and chain.is_planar):  # the spatial entry point fills the workspace
        forward_dynamics(chain, q, qd, planar=planar, ws=ws, out=out)
        D = udu_factors(chain, q).D
        assert np.array_equal(ws.Ihat, np.diag(D))


def test_the_random_chains_seeds_are_the_same_in_another_process():
    """The seeds of the chains above do not depend on the process (Python randomises the hash
    of strings per process), so a failing chain can be built again from its test id."""
    code = ("import sys; sys.path.insert(0, 'tests'); from conftest import stable_seed; "
            "print(stable_seed(('U',), 10, 'wide'))")
    env = {**os.environ, "PYTHONHASHSEED": "random"}
    out = subprocess.run([sys.executable, "-c", code], cwd=Path(__file__).parents[1], env=env,
                         capture_output=True, text=True, check=True, timeout=120)
    assert int(out.stdout) == stable_seed(("U",), 10, "wide")


@pytest.mark.parametrize("kind", ["R", "P"])
@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_a_negative_axis_is_the_positive_one_turned_back(kind, axis):
    """A joint about (along) -e moves as the one about +e with the opposite coordinate:
    qdd_{-e}(q, qd) = -qdd_{+e}(-q, -qd), same tip. It acted as +e (the axis code keyed on
    |v| = 1 and the kernels never saw the sign), and so did an axis within rounding of -e."""
    e = {"x": 0, "y": 1, "z": 2}[axis]
    plus, minus, near = np.eye(3)[e], -np.eye(3)[e], -np.eye(3)[e]
    near[(e + 1) % 3] = 1e-9
    links = [Link(0.7, 1.3, (0.35, 0.02, -0.01), ((0.01, 0, 0), (0, 0.06, 0), (0, 0, 0.06))),
             Link(0.5, 0.8, (0.25, 0.0, 0.03), ((0.005, 0, 0), (0, 0.02, 0), (0, 0, 0.02)))]
    gravity = (0.3, -9.81, 0.7)

    def chain(u):
        return Chain.build(links, [Joint(kind, tuple(u)), Joint("U")], gravity=gravity)

    q, qd = np.array([0.5, 0.3, -0.2]), np.array([0.4, -1.1, 0.6])
    flip = np.array([-1.0, 1.0, 1.0])
    c_plus, c_minus, c_near = chain(plus), chain(minus), chain(near)
    assert c_minus.dof_axis[0] == 3 and c_near.dof_axis[0] == 3 and c_plus.dof_axis[0] == e
    qdd_minus = forward_dynamics(c_minus, q, qd)
    qdd_plus = forward_dynamics(c_plus, flip * q, flip * qd)
    np.testing.assert_allclose(qdd_minus, flip * qdd_plus, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(tip(c_minus, q, qd).position,
                               tip(c_plus, flip * q, flip * qd).position, rtol=0, atol=1e-14)
    assert rel(forward_dynamics(c_near, q, qd), qdd_minus) < 1e-7
    if not np.allclose(qdd_plus, qdd_minus):  # it was the same as +e at the same q
        assert rel(forward_dynamics(c_plus, q, qd), qdd_minus) > 1e-3
