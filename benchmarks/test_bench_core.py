"""qdd per call: the core's RGE-A on U chains of 200..100,000 DOF, pin.aba beside it where it can
be built; a batch of 64 states at 250 DOF (the SIMD tiles on one thread and on every core; the
performance history follows the first per DOF and state); batches of 64 states of the xArm7 and
Talos (a tree's tiles, one thread; ``pin.abaInParallel`` on one thread beside them; the history
follows Talos's); and the planar specialisation's gain over the spatial recursion on R chains.

Run with ``make bench`` (pytest-benchmark). Kernels are warmed up (compiled or loaded from the
on-disk cache) before timing; ``benchmarks/jit_times.py`` reports the compile and load times apart.
Ratios are read from one run: ``make bench`` prints both columns side by side.
"""

from __future__ import annotations

import numpy as np
import pytest

from redysim import Chain, Workspace, forward_dynamics

U_DOF = [200, 2_000, 20_000, 100_000]
# pin.Data allocates nv^3 tensors (docs/design.md, "Reference engines"): 0.5 GB at 200 DOF,
# 13.4 GB at 600 DOF.
PIN_MAX_DOF = 400
BATCH_DOF, BATCH_STATES = 250, 64  # as make bench-engines' test_qdd_batch


def u_chain(dof):
    return Chain.uniform(dof // 2, "U", length=0.02, linear_density=7850 * np.pi * 0.05**2,
                         radius=0.05, inertia="rod", name=f"U{dof // 2}")


def state(model, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-0.3, 0.3, model.n_dof), rng.normal(size=model.n_dof)


@pytest.mark.parametrize("dof", U_DOF)
def test_rge_a_u_chain(benchmark, record, dof):
    chain = u_chain(dof)
    ws, out = Workspace(chain), np.empty(chain.n_dof)
    q, qd = state(chain)
    forward_dynamics(chain, q, qd, ws=ws, out=out)  # warm-up: JIT compile or cache load
    benchmark.group = "qdd, U chains"
    benchmark(forward_dynamics, chain, q, qd, ws=ws, out=out)
    record.update(dof=dof, engine="redysim rge-a", ns_per_dof=benchmark.stats.stats.min / dof * 1e9)


@pytest.mark.parametrize("threads", [1, None], ids=["1-thread", "every-core"])
def test_rge_a_batch_u_chain(benchmark, record, threads):
    """qdd of 64 states at 250 DOF in one call (SIMD tiles), on one thread and on every core
    (the default), as ``make bench-engines``' ``test_qdd_batch[core-250]``: here so that ``make
    bench`` alone gives the performance history its batch figure, ns per DOF and state. The
    history follows the one-thread figure: on this shared 2-core VM (load ~3 from outside) the
    two-thread call waited for a neighbour's time slice in most rounds, fastest 0.19 ms, median
    6.2 ms, against 0.26 and 0.27 ms on one thread (2026-11-26), a spread that would hide any
    step the code makes."""
    from redysim.algorithms.dynamics import default_threads

    dof = BATCH_DOF
    chain = u_chain(dof)
    rng = np.random.default_rng(2)
    Q = rng.uniform(-0.3, 0.3, (BATCH_STATES, dof))
    QD = rng.normal(size=(BATCH_STATES, dof))
    ws, out = Workspace(chain), np.empty((BATCH_STATES, dof))
    forward_dynamics(chain, Q, QD, ws=ws, out=out, threads=threads)  # warm-up: JIT or cache
    benchmark.group = "qdd, batch of 64 states, 250 DOF"
    benchmark(forward_dynamics, chain, Q, QD, ws=ws, out=out, threads=threads)
    record.update(dof=dof, states=BATCH_STATES, kind="batch", engine="redysim rge-a batch",
                  threads=threads or default_threads(),
                  ns_per_dof=benchmark.stats.stats.min / (dof * BATCH_STATES) * 1e9)


ROBOTS = {"xarm7": "XARM7-FALL", "talos": "TALOS-FALL"}  # scenarios of cases/ (ladder.py's)


def robot_batch(name: str):
    """The robot of scenario ROBOTS[name] and the ladder's 64 seeded states near its neutral
    one (``benchmarks/ladder.py``'s ``states``); skips without example-robot-data."""
    from ladder import states

    from redysim.io.scenarios import load_scenario, robot_data_file

    if robot_data_file("talos_reduced.urdf") is None:
        pytest.skip("example-robot-data is not installed (the models extra installs it)")
    model = load_scenario(ROBOTS[name]).model
    return model, *states(model, BATCH_STATES)


@pytest.mark.parametrize("name", ROBOTS)
def test_rge_a_batch_robot(benchmark, record, name):
    """qdd of 64 states of a robot in one call on one thread: a tree's SIMD tiles (free joints,
    placements, branches). The performance history follows Talos's figure, ns per DOF and
    state; ``test_pinocchio_aba_in_parallel_robot`` times Pinocchio's batch on the same
    states."""
    model, Q, V = robot_batch(name)
    ws, out = Workspace(model), np.empty_like(V)
    forward_dynamics(model, Q, V, ws=ws, out=out, threads=1)  # warm-up: JIT compile or cache
    assert ws._tiles is not None  # (in tiles, not row by row)
    benchmark.group = "qdd, batch of 64 robot states, one thread"
    benchmark(forward_dynamics, model, Q, V, ws=ws, out=out, threads=1)
    record.update(dof=model.n_v, states=BATCH_STATES, kind="batch",
                  engine="redysim rge-a batch", threads=1,
                  ns_per_dof=benchmark.stats.stats.min / (model.n_v * BATCH_STATES) * 1e9)


@pytest.mark.parametrize("name", ROBOTS)
def test_pinocchio_aba_in_parallel_robot(benchmark, record, name):
    """``pin.abaInParallel`` on one thread over the same 64 states as
    ``test_rge_a_batch_robot`` (Pinocchio's model built from the core's by
    ``redysim.references``, its qdd checked against the core's first)."""
    from redysim import references

    cls = references.get("pinocchio-aba")
    if not cls.available():
        pytest.skip("pinocchio is not installed")
    model, Q, V = robot_batch(name)
    eng = cls(model)
    pin, pm = eng.lib, eng.pm
    states = [eng._state(Q[k], V[k]) for k in range(BATCH_STATES)]
    PQ = np.asfortranarray(np.array([s for s, _ in states]).T)
    PV = np.asfortranarray(np.array([eng._to_engine(V[k], states[k][1])
                                     for k in range(BATCH_STATES)]).T)
    PT, PA = np.zeros((pm.nv, BATCH_STATES), order="F"), np.zeros((pm.nv, BATCH_STATES), order="F")
    pool = pin.ModelPool(pm, 1)
    pin.abaInParallel(1, pool, PQ, PV, PT, PA)
    want = forward_dynamics(model, Q, V, threads=1)
    got = np.array([eng._from_engine(PA[:, k], b) + (eng._c(b) if b else 0.0)  # (as qdd)
                    for k, (_, b) in enumerate(states)])
    assert np.abs(got - want).max() <= 1e-8 * np.abs(want).max()  # (as ladder.py checks)
    benchmark.group = "qdd, batch of 64 robot states, one thread"
    benchmark(pin.abaInParallel, 1, pool, PQ, PV, PT, PA)
    record.update(dof=model.n_v, states=BATCH_STATES, kind="batch",
                  engine=f"pinocchio {pin.__version__} abaInParallel", threads=1,
                  ns_per_dof=benchmark.stats.stats.min / (model.n_v * BATCH_STATES) * 1e9)


@pytest.mark.parametrize("dof", U_DOF[:2])
def test_rge_a_kernel_alone_u_chain(benchmark, record, dof):
    """The compiled entry point that forward_dynamics calls, called directly: the difference is
    forward_dynamics' Python (its argument handling, ~0.5 us here). Not a user's path: shown to
    say where the time goes."""
    from redysim.algorithms._kernels.entry import RGE_A

    chain = u_chain(dof)
    ws, out = Workspace(chain), np.empty(chain.n_dof)
    q, qd = state(chain)
    args = (ws.kernel_f, ws.kernel_i, q, qd, ws.zeros, ws.scratch, out)
    entry = RGE_A.compiled
    assert entry(*args) == 0.0
    benchmark.group = "qdd, U chains"
    benchmark(entry, *args)
    assert np.array_equal(out, forward_dynamics(chain, q, qd))  # the same qdd
    record.update(dof=dof, engine="redysim rge-a kernel alone",
                  ns_per_dof=benchmark.stats.stats.min / dof * 1e9)


@pytest.mark.parametrize("dof", [d for d in U_DOF if d <= PIN_MAX_DOF])
def test_pinocchio_aba_u_chain(benchmark, record, dof):
    pin = pytest.importorskip("pinocchio")
    chain = u_chain(dof)
    model = pin.Model()
    parent = 0
    for k in range(chain.n_links):
        placement = pin.SE3(np.eye(3), np.array([chain.length[k - 1] if k else 0.0, 0.0, 0.0]))
        joint = pin.JointModelUniversal(np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]))
        parent = model.addJoint(parent, joint, placement, f"j{k}")
        model.appendBodyToJoint(parent, pin.Inertia(chain.mass[k], chain.com[k].copy(),
                                                    chain.inertia_com[k].copy()),
                       pin.SE3.Identity())
    model.gravity.linear = chain.gravity.copy()
    data = pin.Data(model)
    q, qd = state(chain)
    tau = np.zeros(chain.n_dof)
    benchmark.group = "qdd, U chains"
    benchmark(pin.aba, model, data, q, qd, tau)
    record.update(dof=dof, engine=f"pinocchio {pin.__version__} aba",
                  ns_per_dof=benchmark.stats.stats.min / dof * 1e9)


@pytest.mark.parametrize("links", [1_000, 100_000])
@pytest.mark.parametrize("planar", [True, False], ids=["planar", "spatial"])
def test_planar_gain(benchmark, record, links, planar):
    chain = Chain.uniform(links, "R", length=1.0, mass=8.83, radius=0.02, inertia="cylinder")
    ws, out = Workspace(chain), np.empty(chain.n_dof)
    q, qd = state(chain)
    forward_dynamics(chain, q, qd, planar=planar, ws=ws, out=out)
    benchmark.group = f"qdd, planar R chain, {links} links"
    benchmark(forward_dynamics, chain, q, qd, planar=planar, ws=ws, out=out)
    record.update(dof=links, engine="planar" if planar else "spatial",
                  ns_per_dof=benchmark.stats.stats.min / links * 1e9)
