"""Coupled joints (Model.couplings: URDF mimic joints, MJCF joint equalities of degree 1): the
coupled forward dynamics against the reduced-coordinate solve written independently, inverse of
forward, energy kept and the couplings held over a run, the refusals by name, locking, export
round trips, and the engines that build couplings (Pinocchio's mimic joints, MuJoCo's joint
equality) against the core."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import stable_seed
from test_trees import random_configuration, random_tree

import redysim
from redysim import Coupling
from redysim.errors import CaseError, StateError


def coupled_tree(seed, free=True):
    """A random tree (free base or not) with up to three couplings among its R and P joints,
    one of them with a negative multiplier and an offset."""
    model = random_tree(seed, n_bodies=10, free=free, fixed=1)
    rng = np.random.default_rng(seed)
    names = [n for n, t in zip(model.joint_names, model.joint_types, strict=True)
             if t in ("R", "P")]
    rng.shuffle(names)
    pairs = [(names[i], names[i + 1]) for i in range(0, min(len(names) - 1, 6), 2)]
    couplings = [Coupling(f, ld, float(rng.choice([-1.0, 1.0])) * rng.uniform(0.3, 2.0),
                          rng.uniform(-0.3, 0.3)) for f, ld in pairs]
    assert couplings, "a tree with R or P joints to couple"
    return model.with_couplings(couplings)


def state(model, rng):
    q = random_configuration(rng, model)
    return model.couple(q, rng.normal(size=model.n_v))


def reduced_solve(model, q, v, tau):
    """qdd from the reduced coordinates, written apart from the core's method: v = G v_r,
    (G^T M G) qdd_r = G^T (tau + phi_tree), qdd = G qdd_r."""
    n = model.n_v
    _, _, fv, lv, m, _ = model.coupling_index
    keep = [i for i in range(n) if i not in set(fv.tolist())]
    G = np.zeros((n, len(keep)))
    G[keep, np.arange(len(keep))] = 1.0
    for f, ld, mu in zip(fv, lv, m, strict=True):
        G[f, keep.index(ld)] = mu
    M = redysim.mass_matrix(model.tree, q)
    rhs = G.T @ redysim.phi(model.tree, q, v, tau)
    return G @ np.linalg.solve(G.T @ M @ G, rhs)


@pytest.mark.parametrize("seed", range(6))
def test_coupled_qdd_is_the_reduced_coordinates_solve(seed):
    model = coupled_tree(stable_seed("coupled", seed), free=seed % 2 == 0)
    rng = np.random.default_rng(seed)
    q, v = state(model, rng)
    tau = rng.normal(size=model.n_v)
    qdd = redysim.forward_dynamics(model, q, v, tau)
    want = reduced_solve(model, q, v, tau)
    assert np.abs(qdd - want).max() < 1e-11 * np.abs(want).max()
    _, _, fv, lv, m, _ = model.coupling_index
    assert np.array_equal(qdd[fv], m * qdd[lv])  # on the couplings exactly
    # inverse of forward: the tree's torques for this motion give it back
    tau2 = redysim.inverse_dynamics(model, q, v, qdd)
    back = redysim.forward_dynamics(model, q, v, tau2)
    assert np.abs(back - qdd).max() < 1e-11 * np.abs(qdd).max()
    # a batch is its rows
    Q, V = np.stack([q, q]), np.stack([v, v])
    assert np.array_equal(redysim.forward_dynamics(model, Q, V, tau)[1], qdd)


def structured(kind):
    """Coupled models of given shapes (the couplings' qdd in RGE-A's recursion walks each
    coupling's paths to the root; these put the paths where it could go wrong):

    - ``chain``: a spatial serial chain (R about y, x and z, a U and an S joint, a P joint), a
      follower before its leader, a negative multiplier, two couplings, a U joint on the paths;
    - ``branches``: a tree whose couplings join joints of different branches (their paths meet
      at the base), one of them followed by a joint nearer the base, three couplings;
    - ``free``: the same tree on a free base, couplings sharing a leader."""
    if kind == "chain":
        links = [redysim.Link.uniform(0.3 + 0.1 * k, 1.0 + 0.3 * k, 0.04, "cylinder")
                 for k in range(8)]
        joints = [redysim.Joint("R", "y"), redysim.Joint("U"), redysim.Joint("R", "x"),
                  redysim.Joint("P"), redysim.Joint("R"), redysim.Joint("S"),
                  redysim.Joint("R", "y"), redysim.Joint("R")]
        chain = redysim.Chain.build(links, joints, gravity=(0.0, 0.0, -9.81))
        return chain.with_couplings([Coupling("joint1", "joint5", -0.7, 0.1),
                                     Coupling("joint8", "joint3", 1.3, -0.2)])
    rng = np.random.default_rng(stable_seed("coupled-structured", kind))
    parents = [-1, 0, 1, 2, 1, 4, 0, 6, 7]  # branches at bodies 0 and 1
    types = ["free" if kind == "free" else "R", "R", "P", "R", "R", "R", "R", "U", "P"]
    bodies, joints = [], []
    for k, t in enumerate(types):
        R = np.linalg.qr(rng.normal(size=(3, 3)))[0]  # principal axes, moments a rigid body's
        inertia = R @ np.diag(rng.uniform(0.1, 0.2, 3)) @ R.T
        bodies.append(redysim.Body(f"b{k}", 0.5 + rng.uniform(), tuple(rng.normal(scale=0.1,
                                                                                   size=3)),
                                   tuple(map(tuple, inertia))))
        joints.append(redysim.TreeJoint(f"j{k}", t, None if t in ("free", "U") else
                                        tuple(rng.normal(size=3)),
                                        translation=(0.0, 0.0, 0.0) if t == "free" else
                                        tuple(rng.normal(scale=0.3, size=3))))
    model = redysim.Model.build(bodies, joints, parents, gravity=(0.0, 0.0, -9.81))
    if kind == "free":
        return model.with_couplings([Coupling("j3", "j5", 0.8), Coupling("j8", "j5", -1.1, 0.05),
                                     Coupling("j2", "j6", 0.4)])
    return model.with_couplings([Coupling("j3", "j5", 0.8), Coupling("j1", "j8", -1.1, 0.05),
                                 Coupling("j4", "j6", 0.6, 0.2)])


@pytest.mark.parametrize("kind", ["chain", "branches", "free"])
def test_every_door_gives_the_reduced_coordinates_solve(kind):
    """The coupled qdd (RGE-A with the couplings in its recursion) against the reduced solve
    G^T M G x = G^T (tau - h) from the GIM and inverse dynamics, on a chain, couplings across
    branches, on a free base; the public call, the evaluator, a batch (one thread and two) and
    a run's compiled derivative give the same bits."""
    from redysim.algorithms._kernels.system import derivative
    from redysim.algorithms.system import System

    model = structured(kind)
    assert redysim.Workspace(model).coupled and not model.is_planar
    rng = np.random.default_rng(stable_seed("every-door", kind))
    fd = redysim.evaluator(model)
    rows = [state(model, rng) for _ in range(40)]
    Q, V = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
    T = rng.normal(size=V.shape)
    system = System(model, method="rge-a")
    sd, extras = system.kernel
    for threads in (1, 2):
        batch = redysim.forward_dynamics(model, Q, V, T, threads=threads)
        for i in (0, 17, 39):
            q, v, tau = Q[i], V[i], T[i]
            want = reduced_solve(model, q, v, tau)
            got = redysim.forward_dynamics(model, q, v, tau)
            assert np.abs(got - want).max() < 1e-12 * np.abs(want).max()
            _, _, fv, lv, m, _ = model.coupling_index
            assert np.array_equal(got[fv], m * got[lv])
            assert np.array_equal(fd(q, v, tau), got)
            assert np.array_equal(batch[i], got)
    q, v = Q[5], V[5]
    y, dy = np.concatenate((q, v)), np.empty(model.n_q + model.n_v)
    assert derivative(sd, extras, 0.0, y, dy)
    assert np.array_equal(dy[model.n_q:], redysim.forward_dynamics(model, q, v))


def test_a_run_keeps_the_couplings_and_the_energy():
    """The constraint forces do no work: energy is kept; each step's followers are put back on
    their leaders, and the largest correction is rounding."""
    model = coupled_tree(stable_seed("coupled-run"), free=False)
    q, v = state(model, np.random.default_rng(5))
    sim = redysim.simulate(model, 1.0, q0=q, v0=v, rtol=1e-10, atol=1e-12)
    assert sim.status == 0
    assert np.abs(sim.delta_M).max() < 1e-8
    assert sim.residual_q < 1e-12 and sim.residual_v < 1e-12
    fq, lq, fv, lv, m, off = model.coupling_index
    assert np.abs(sim.q[:, fq] - (m * sim.q[:, lq] + off)).max() < 1e-14
    assert np.abs(sim.v[:, fv] - m * sim.v[:, lv]).max() < 1e-12


@pytest.mark.parametrize("method, kw", [("ode45", {"rtol": 1e-8, "atol": 1e-10}),
                                        ("dop853", {"rtol": 1e-9, "atol": 1e-11}),
                                        ("rk4", {"h": 1e-3})])
@pytest.mark.parametrize("free, damping", [(True, 0.0), (False, 0.2)])
def test_a_coupled_motion_steps_in_compiled_code_in_the_same_bits(method, kw, free, damping):
    """A coupled tree steps in compiled code (Simulator.compiled): the same steps, samples,
    energy and coupling residuals as the Python loop, bit for bit; its qdd (the steps' own
    Featherstone solve) is the reduced-coordinate solve's to rounding."""
    from test_integrate import _compiled_and_python_runs

    from redysim.algorithms._kernels.system import coupled_qdd
    from redysim.simulation import simulator

    model = coupled_tree(stable_seed("coupled-compiled", free), free=free)
    q, v = state(model, np.random.default_rng(11))
    a, b = _compiled_and_python_runs(model, 0.25, q0=q, v0=v, integrator=method,
                                     damping=damping, **kw)
    assert (a.residual_q, a.residual_v) == (b.residual_q, b.residual_v)
    assert a.residual_q < 1e-12 and a.residual_v < 1e-10
    if not damping:
        assert np.abs(a.delta_M).max() < (1e-5 if method == "rk4" else 1e-7)
    system = simulator(model, 0.1).system
    ws, tau, got = system.ws, np.random.default_rng(3).normal(size=model.n_v), np.empty(model.n_v)
    assert coupled_qdd(ws.kernel_f, ws.kernel_i, ws.scratch, q, v, tau, got) == 0.0
    want = reduced_solve(model, q, v, tau)
    assert np.abs(got - want).max() < 1e-11 * np.abs(want).max()


@pytest.mark.parametrize("file", ["panda_description/urdf/panda.urdf", "talos_full_v2.urdf"])
def test_robots_with_mimic_joints_step_in_compiled_code_in_the_same_bits(file):
    """Panda (a finger mimic) and Talos full (12 gripper mimics, floating) fall in compiled code
    as in the Python loop, bit for bit."""
    from test_integrate import _compiled_and_python_runs
    from test_trees import robot_urdf

    model = redysim.load_model(robot_urdf(file), floating=file.startswith("talos"))
    assert model.couplings
    rng = np.random.default_rng(stable_seed("mimic-compiled", file))
    q, v = model.couple(model.neutral(), 0.3 * rng.normal(size=model.n_v))
    a, b = _compiled_and_python_runs(model, 0.2, q0=q, v0=v, rtol=1e-7, atol=1e-9)
    if model.damping.any():  # the file's joint damping (<dynamics damping>): E only falls,
        # by the dampers' work W (delta_M is the balance E - W - E0 per kg)
        assert np.diff(a.energy).max() < 1e-9 * model.total_mass and a.energy[-1] < a.E0
        assert a.work[-1] < 0 and np.array_equal(a.work, b.work)
    assert np.abs(a.delta_M).max() < 1e-5


def test_a_state_off_the_couplings_is_refused_by_name():
    model = coupled_tree(stable_seed("coupled-off"), free=False)
    q, v = state(model, np.random.default_rng(1))
    c = model.couplings[0]
    k = model.joint_qoff[model.joint_names.index(c.follower)]
    bad = q.copy()
    bad[k] += 1e-3
    with pytest.raises(StateError, match=f"joint '{c.follower}', follows joint '{c.leader}'"):
        redysim.forward_dynamics(model, bad, v)
    with pytest.raises(StateError, match="model.couple"):
        redysim.inverse_dynamics(model, q, v, np.ones(model.n_v))
    bad_v = v.copy()
    bad_v[model.joint_voff[model.joint_names.index(c.follower)]] += 1e-3
    for q0, v0 in ((bad, v), (q, bad_v)):  # a run's start too (its steps take it as given)
        with pytest.raises(StateError, match=f"joint '{c.follower}', follows"):
            redysim.simulate(model, 0.1, q0=q0, v0=v0)
    fd = redysim.evaluator(model)  # (its lean entry refuses it: the checked path names it)
    with pytest.raises(StateError, match=f"joint '{c.follower}', follows joint '{c.leader}'"):
        fd(bad, v)
    with pytest.raises(StateError, match=f"state 1 of the batch .*joint '{c.follower}'"):
        redysim.forward_dynamics(model, np.stack([q, bad]), np.stack([v, v]))


@pytest.mark.parametrize("couplings, field, fragment", [
    ([Coupling("nope", "j1")], "couplings[0].follower", "no such joint"),
    ([Coupling("j1", "j1")], "couplings[0].leader", "cannot follow itself"),
    ([Coupling("j2", "j1"), Coupling("j2", "j3")], "couplings[1].follower", "follows twice"),
    ([Coupling("j2", "j1"), Coupling("j3", "j2")], "couplings[1].leader", "itself follows"),
    ("j1", "couplings", "a list of Coupling"),
])
def test_bad_couplings_are_refused_by_name(couplings, field, fragment):
    model = redysim.Chain.uniform(4, "R", mass=1.0)
    model = redysim.Model.build(
        [redysim.Body(f"b{k}", 1.0, (0.5, 0, 0), ((0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1)))
         for k in range(4)],
        [redysim.TreeJoint(f"j{k}", "R", "z", translation=(0.0 if k == 0 else 1.0, 0, 0))
         for k in range(4)], [-1, 0, 1, 2])
    with pytest.raises(CaseError) as e:
        model.with_couplings(couplings)
    assert e.value.field == field and fragment in e.value.problem


def test_a_coupling_needs_one_axis_joints_and_finite_numbers():
    model = redysim.Chain.uniform(3, "U", mass=1.0)
    with pytest.raises(CaseError, match="a U joint"):
        model.with_couplings([Coupling(model.joint_names[1], model.joint_names[0])])
    with pytest.raises(CaseError, match="finite"):
        Coupling("a", "b", math.nan)


def test_locking_keeps_the_couplings_and_refuses_a_coupled_joint():
    model = coupled_tree(stable_seed("coupled-lock"), free=False)
    coupled = {n for c in model.couplings for n in (c.follower, c.leader)}
    free = [n for n, t in zip(model.joint_names, model.joint_types, strict=True)
            if n not in coupled and t in ("R", "P")]
    locked = model.locked({free[0]: 0.3})
    assert locked.couplings == model.couplings
    with pytest.raises(CaseError, match="a coupled joint"):
        model.locked({model.couplings[0].follower: 0.0})


def test_export_writes_the_couplings_back(tmp_path):
    """URDF <mimic> and MJCF joint <equality>: read back, the same couplings and qdd."""
    pytest.importorskip("mujoco")
    from redysim.io.export import to_mjcf, to_urdf

    rng = np.random.default_rng(stable_seed("coupled-export"))
    bodies, joints = [], []
    for k in range(6):  # R and P joints only: one coordinate each, matched by name below
        bodies.append(redysim.Body(f"b{k}", 1.0 + k / 5, tuple(rng.normal(scale=0.1, size=3)),
                                   ((0.2, 0.01, 0.0), (0.01, 0.3, 0.0), (0.0, 0.0, 0.4))))
        joints.append(redysim.TreeJoint(f"j{k}", "RP"[k % 2], tuple(rng.normal(size=3)),
                                        translation=tuple(rng.normal(scale=0.3, size=3))))
    model = redysim.Model.build(bodies, joints, [-1, 0, 1, 1, 3, 0],
                                gravity=(0.0, 0.0, -9.81)).with_couplings(
        [Coupling("j2", "j1", -1.5, 0.1), Coupling("j5", "j3", 0.5, 0.0)])
    q, v = state(model, rng)
    want = redysim.forward_dynamics(model, q, v)
    for name, text in (("m.urdf", to_urdf(model)), ("m.xml", to_mjcf(model))):
        path = tmp_path / name
        path.write_text(text)
        back = redysim.load_model(path)
        assert sorted(back.couplings, key=lambda c: c.follower) == \
            sorted(model.couplings, key=lambda c: c.follower)
        order = [back.joint_names.index(n) for n in model.joint_names]  # its q slot of each
        qb, vb = np.empty(6), np.empty(6)
        qb[order], vb[order] = q, v
        got = redysim.forward_dynamics(back, qb, vb)[order]
        assert np.abs(got - want).max() < 1e-10 * np.abs(want).max(), name


# --------------------------------------------------------------------------- engines
ROBOTS = (("panda_description/urdf/panda.urdf", False),
          ("baxter_description/urdf/baxter.urdf", False),
          ("talos_data/robots/talos_full_v2.urdf", True))  # 12 mimic joints in its grippers


def robot(file, floating):
    from redysim.io.scenarios import robot_data_file

    path = robot_data_file(file)
    if path is None:
        pytest.skip("example-robot-data is not installed")
    return path, redysim.load_model(path, floating=floating)


def robot_state(model, seed):
    rng = np.random.default_rng(seed)
    q = model.initial()
    moving = slice(7, None) if model.quaternions.size else slice(None)
    q[moving] += rng.uniform(-0.5, 0.5, q[moving].size)
    q, v = model.couple(q, rng.normal(size=model.n_v))
    return q, v, rng.normal(size=model.n_v)


@pytest.mark.engine
@pytest.mark.parametrize("file, floating", ROBOTS)
def test_pinocchios_mimic_joints_give_the_cores_coupled_qdd(file, floating):
    """pinocchio-crba on Pinocchio's mimic joints (transformJointIntoMimic, crba and
    nonLinearEffects of the coupled model) against the core's Featherstone method; Pinocchio's
    ABA refuses them by name (pinocchio-crba builds them). The other engines:
    tests/test_engines_couplings.py."""
    from engine_chains import engine_or_skip

    _, model = robot(file, floating)
    assert model.couplings
    q, v, tau = robot_state(model, stable_seed("mimic", file))
    core = redysim.forward_dynamics(model, q, v, tau)
    eng = engine_or_skip("pinocchio-crba")(model)
    assert np.abs(eng.qdd(q, v, tau) - core).max() < 1e-12 * np.abs(core).max()
    from redysim import references

    for name in ("pinocchio-aba", "pinocchio-aba-ryrz"):
        lim = references.get(name).limits(model)
        assert not lim.ok and "pinocchio-crba builds them" in lim.reason, name


@pytest.mark.engine
@pytest.mark.parametrize("file", ["panda_description/urdf/panda.urdf",
                                  "baxter_description/urdf/baxter.urdf"])
def test_pinocchios_own_urdf_reader_couples_as_ours(file):
    """Pinocchio reading the URDF itself (buildModelFromUrdf(..., mimic=True): its own parser
    and mimic joints, no adapter of ours): its reduced crba and nonLinearEffects, solved, give
    the core's qdd on the independent joints (Talos's v2 URDF its reader refuses: 'The parent
    joint of the mimic joint is not in the kinematic tree', 4.1.0)."""
    pin = pytest.importorskip("pinocchio")
    path, model = robot(file, False)
    pm = pin.buildModelFromUrdf(str(path), mimic=True)
    data = pm.createData()
    q, v, tau = robot_state(model, stable_seed("mimic-own", file))
    _, _, fv, _, _, _ = model.coupling_index
    mine = [k for k, name in enumerate(model.joint_names)
            if model.joint_voff[k] not in set(fv.tolist())]
    theirs = [pm.joints[pm.getJointId(model.joint_names[k])].idx_v for k in mine]
    assert pm.nv == len(mine) == model.n_v - len(model.couplings)
    qp, vp = np.empty(pm.nq), np.empty(pm.nv)
    qp[theirs], vp[theirs] = q[mine], v[mine]
    M = pin.crba(pm, data, qp)
    M = np.triu(M) + np.triu(M, 1).T
    _, _, _, lv, m, _ = model.coupling_index
    G = np.zeros((model.n_v, pm.nv))  # v = G v_reduced, in the core's order
    G[mine, theirs] = 1.0
    for f, ld, mu in zip(fv, lv, m, strict=True):
        G[f] = mu * G[ld]
    qdd_r = np.linalg.solve(M, G.T @ tau - pin.nonLinearEffects(pm, data, qp, vp))
    core = redysim.forward_dynamics(model, q, v, tau)
    assert np.abs(core[mine] - qdd_r[theirs]).max() < 1e-10 * np.abs(core).max()


@pytest.mark.engine
@pytest.mark.parametrize("file, floating", ROBOTS)
def test_mujocos_joint_equality_is_the_coupling_softened_by_its_regulariser(file, floating):
    """MuJoCo holds a coupling softly: (A + R) f = -J qacc_smooth with R its regulariser
    (efc_R; aref = 0 on a coupled state). The core's Featherstone method with MuJoCo's R added
    to J M^-1 J^T gives MuJoCo's qacc; without it, the hard answer, off by ~R / A."""
    from engine_chains import engine_or_skip

    _, model = robot(file, floating)
    q, v, tau = robot_state(model, stable_seed("mimic-mj", file))
    eng = engine_or_skip("mujoco")(model)
    got = eng.qdd(q, v, tau)
    d, mm = eng.mjdata, eng.mjmodel
    ids = [mm.equality(f"coupling{i}").id for i in range(len(model.couplings))]
    assert d.nefc == len(ids)
    R = np.empty(len(ids))
    R[[ids.index(int(e)) for e in d.efc_id[:d.nefc]]] = d.efc_R[:d.nefc]
    qdd0 = redysim.forward_dynamics(model.tree, q, v, tau)
    _, _, fv, lv, m, _ = model.coupling_index
    J = np.zeros((len(ids), model.n_v))
    J[np.arange(len(ids)), fv] = 1.0
    J[np.arange(len(ids)), lv] -= m
    X = np.column_stack([redysim.forward_dynamics(model.free_tree, q, np.zeros(model.n_v), r)
                         for r in J])
    soft = qdd0 + X @ np.linalg.solve(J @ X + np.diag(R), -(J @ qdd0))
    assert np.abs(got - soft).max() < 1e-9 * np.abs(got).max()
    hard = redysim.forward_dynamics(model, q, v, tau)
    assert np.abs(got - hard).max() > 1e-9 * np.abs(hard).max()  # the softness is seen


def test_a_coupled_batch_takes_one_tau_or_a_row_each_and_refuses_other_shapes():
    model = coupled_tree(stable_seed("coupled-batch"), free=False)
    rng = np.random.default_rng(4)
    (q1, v1), (q2, v2) = state(model, rng), state(model, rng)
    tau = rng.normal(size=model.n_v)
    Q, V = np.stack([q1, q2]), np.stack([v1, v2])
    one = redysim.forward_dynamics(model, Q, V, tau)
    assert np.array_equal(one[1], redysim.forward_dynamics(model, q2, v2, tau))
    assert np.array_equal(redysim.forward_dynamics(model, Q, V, np.stack([tau, tau])), one)
    with pytest.raises(StateError, match="tau"):
        redysim.forward_dynamics(model, Q, V, np.ones(3))
