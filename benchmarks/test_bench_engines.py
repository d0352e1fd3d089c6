"""Side by side: qdd per call for the core and every reference engine on U chains, 20 to
100,000 DOF, each engine up to its measured limit; and the cost of one native step at 2,000 DOF
(or the engine's nearest feasible size).

    .venv/bin/python -m pytest benchmarks/test_bench_engines.py --benchmark-only \
        --benchmark-json=results/bench_engines.json
    .venv/bin/python -m redysim.references.report_bench results/bench_engines.json

The chain is the RE-U steel rod (20 mm links, rod inertia); the state a seeded small-angle one.
Batches (``test_qdd_batch``): 64 states at 20, 250 and 2,000 DOF, the core's batch (SIMD tiles
on numba's threads), the same batch row by row (``simd=False``: the single-state kernel on Python
threads), and the core and ``pin.aba`` called state by state.
Robots (``test_qdd_robot``): URDFs of example-robot-data, an arm (UR5, fixed base) and a humanoid
(Talos, reduced, floating base), the core beside ``pin.aba`` called from Python on Pinocchio's
own model of the same file (tests/test_trees.py checks the two models agree to 1e-13).
Models are built once per module (build time is not timed here; references/limits.toml has it).
The core is warmed up (numba JIT) before timing. A size beyond an engine's limit is skipped with
the limit's reason, never attempted.
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np
import pytest

import redysim
from redysim import Workspace, references

pytestmark = pytest.mark.engine

SIZES_DOF = (20, 200, 2000, 20000, 100000)
STEP_DOF = 2000
STEP_H = 1e-5  # s; a step length the RE-U chains need (docs/design.md, "Integrators")
ENGINES = ("core", *references.ENGINES)

_CHAINS: dict = {}
_BUILT: dict = {}


def chain_of(dof: int) -> redysim.Chain:
    if dof not in _CHAINS:
        _CHAINS[dof] = redysim.Chain.uniform(dof // 2, "U", length=0.02, linear_density=61.6538,
                                             radius=0.05, inertia="rod", name=f"U{dof // 2}")
    return _CHAINS[dof]


def state(model):
    rng = np.random.default_rng(0)
    return rng.uniform(-0.1, 0.1, model.n_dof), rng.uniform(-0.1, 0.1, model.n_dof)


def machine() -> dict:
    return {"machine": platform.machine(), "processor": platform.processor() or "unknown",
            "cpus": os.cpu_count(), "python": platform.python_version(),
            "numpy": np.__version__, "redysim": redysim.__version__}


def engine_for(name: str, dof: int):
    cls = references.get(name)
    if not cls.available():
        pytest.skip(f"{name}: package {cls.package!r} not installed")
    chain = chain_of(dof)
    lim = cls.limits(chain)
    if not lim.ok:
        pytest.skip(lim.reason)
    key = (name, dof)
    if key not in _BUILT:
        _BUILT.clear()  # keep one model at a time: the large ones are hundreds of MiB
        _BUILT[key] = cls(chain)
    return _BUILT[key]


@pytest.mark.parametrize("dof", SIZES_DOF)
@pytest.mark.parametrize("name", ENGINES)
def test_qdd(benchmark, name, dof):
    benchmark.group = f"qdd-{dof}"
    chain = chain_of(dof)
    q, qd = state(chain)
    info = {"engine": name, "dof": dof, "kind": "qdd", **machine()}
    if name == "core":
        ws = Workspace(chain)
        redysim.forward_dynamics(chain, q, qd, ws=ws)  # JIT warm-up, not timed
        info["version"] = redysim.__version__
        benchmark.extra_info.update(info)
        out = benchmark(redysim.forward_dynamics, chain, q, qd, ws=ws)
    else:
        eng = engine_for(name, dof)
        info["version"] = eng.version
        benchmark.extra_info.update(info)
        out = benchmark(eng.qdd, q, qd)
    assert np.all(np.isfinite(out))


BATCH_STATES = 64
BATCH_DOF = (20, 250, 2000)


@pytest.mark.parametrize("dof", BATCH_DOF)
@pytest.mark.parametrize("name", ["core", "core-rows", "core-single", "pinocchio-aba"])
def test_qdd_batch(benchmark, name, dof):
    """qdd of 64 states: the core's batch (SIMD tiles, split over every core), the same batch
    row by row (``simd=False``), the core called state by state from Python, and pin.aba
    (through its adapter) state by state. Time per 64 states; the report gives ns per DOF per
    state."""
    benchmark.group = f"qdd-batch-{dof}"
    chain = chain_of(dof)
    rng = np.random.default_rng(2)
    Q = rng.uniform(-0.1, 0.1, (BATCH_STATES, dof))
    QD = rng.uniform(-0.1, 0.1, (BATCH_STATES, dof))
    info = {"engine": name, "dof": dof, "kind": "batch", "states": BATCH_STATES, **machine()}
    if name.startswith("core"):
        ws = Workspace(chain)
        out = np.empty((BATCH_STATES, dof))
        simd = name == "core"
        redysim.forward_dynamics(chain, Q, QD, ws=ws, out=out, simd=simd)  # JIT warm-up
        info["version"] = redysim.__version__
        info["threads"] = (redysim.algorithms.threads.default_threads()
                           if name != "core-single" else 1)
        if name in ("core", "core-rows"):
            def call():
                return redysim.forward_dynamics(chain, Q, QD, ws=ws, out=out, simd=simd)
        else:
            def call():
                for i in range(BATCH_STATES):
                    redysim.forward_dynamics(chain, Q[i], QD[i], ws=ws, out=out[i])
                return out
    else:
        eng = engine_for(name, dof)
        info["version"] = eng.version
        out = np.empty((BATCH_STATES, dof))

        def call():
            for i in range(BATCH_STATES):
                out[i] = eng.qdd(Q[i], QD[i])
            return out
    benchmark.extra_info.update(info)
    result = benchmark(call)
    assert np.all(np.isfinite(result))


ROBOTS = {"ur5": ("ur_description/urdf/ur5_robot.urdf", False),
          "talos": ("talos_reduced.urdf", True)}


def robot_path(file: str) -> str:
    from importlib import metadata

    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed (the test extra installs it)")
    return str(dist.locate_file(next(f for f in dist.files if str(f).endswith("/" + file))))


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("name", ["core", "pinocchio-aba"])
def test_qdd_robot(benchmark, name, robot):
    """qdd per call on a robot at a seeded state near the neutral one; mimic joints (Talos's
    grippers) move independently in both (Pinocchio's default)."""
    file, floating = ROBOTS[robot]
    path = robot_path(file)
    rng = np.random.default_rng(1)
    benchmark.group = f"qdd-robot-{robot}"
    if name == "core":
        model = redysim.load_model(path, floating=floating, mimic="independent")
        q = model.neutral()
        quaternion = [i + j for i in model.quaternions for j in range(4)]
        plain = np.setdiff1d(np.arange(model.n_q), quaternion)
        q[plain] += rng.uniform(-0.3, 0.3, plain.size)
        v = rng.uniform(-0.3, 0.3, model.n_v)
        ws = Workspace(model)
        redysim.forward_dynamics(model, q, v, ws=ws)  # JIT warm-up, not timed
        version, dof = redysim.__version__, model.n_v
        call = (redysim.forward_dynamics, model, q, v)
        kw = {"ws": ws}
    else:
        pin = pytest.importorskip("pinocchio")
        pm = (pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer()) if floating
              else pin.buildModelFromUrdf(path))
        data = pm.createData()
        q = pin.neutral(pm)
        q[7 if floating else 0:] += rng.uniform(-0.3, 0.3, pm.nq - (7 if floating else 0))
        v = rng.uniform(-0.3, 0.3, pm.nv)
        tau = np.zeros(pm.nv)
        version, dof = pin.__version__, pm.nv
        call = (pin.aba, pm, data, q, v, tau)
        kw = {}
    benchmark.extra_info.update({"engine": name, "dof": dof, "robot": robot, "kind": "qdd",
                                 "version": version, **machine()})
    out = benchmark(*call, **kw)
    assert np.all(np.isfinite(out))


def step_dof(name: str) -> int:
    """STEP_DOF, or the largest even DOF the engine's limit allows below it."""
    max_dof = references.load_limits()["engine"][name]["max_dof"]
    return min(STEP_DOF, max_dof - max_dof % 2)


@pytest.mark.parametrize("name", [n for n, c in references.ENGINES.items() if c.integrators])
def test_native_step(benchmark, name):
    """One step of the engine's default integrator from the same state each round (the state is
    reset, untimed, before each round: a long run of steps would time a drifting state).
    Pinocchio has no integrator of its own (references/pinocchio_engine.py)."""
    dof = step_dof(name)
    benchmark.group = "native-step"
    eng = engine_for(name, dof)
    q, qd = state(chain_of(dof))
    eng.sim_reset(q, qd, STEP_H)
    t0 = time.perf_counter()
    eng.step_once()
    rounds = int(min(200, max(3, 2.0 / max(time.perf_counter() - t0, 1e-9))))
    benchmark.extra_info.update({"engine": name, "dof": dof, "kind": "step", "h": STEP_H,
                                 "integrator": eng.integrator, "version": eng.version,
                                 **machine()})
    benchmark.pedantic(eng.step_once, setup=lambda: eng.sim_reset(q, qd, STEP_H),
                       rounds=rounds, iterations=1, warmup_rounds=1)
    assert np.all(np.isfinite(eng.sim_state()[0]))
