"""The latency/throughput ladder: what one state's forward dynamics costs the core and every
engine, from a call from Python up to a whole simulated second, on an arm, a humanoid and a rope.

    .venv/bin/python benchmarks/ladder.py [--rounds 21] [--round-ms 20] [--no-second]
        [--out results/bench/ladder.json]

Systems (each a scenario of ``cases/``, so that the last rung runs the same motion): the xArm7
(7 DOF, fixed base, ``XARM7-FALL``), Talos reduced on a floating base (38 DOF, ``TALOS-FALL``)
and RE-U125-L1's rope (125 U links, 250 DOF) swinging from 30 degrees off the vertical
(``cases/ladder/swing-U125-L1.toml``: RE-U125-L1 itself whips at 0.45 s, after which no two
integrators agree to 1e-6 m). Each engine builds the core's own model
(``redysim.references``; one adapter per engine, as ``redysim compare`` picks them) and its
qdd is checked against the core's before anything is timed.

The rungs, per system, in one process:

1. **call** -- one state's qdd from Python: the core's evaluator ``fd(q, v)``
   (``redysim.evaluator``) and its default call ``forward_dynamics(model, q, v)``;
   ``pin.aba(model, data, q, v, tau)``; MuJoCo's ``qpos`` and ``qvel`` set and ``mj_forward``;
   DART, Exudyn and Drake as their adapters call them, on the engine's own coordinates (state
   set, dynamics, result copied: DART's ``computeForwardDynamics``, Exudyn's system solve,
   Drake's ``CalcForwardDynamics``).
2. **compiled** -- the same computation repeated inside compiled code, per state: the core's
   kernel called 1,000 times from a numba loop (what its compiled stepping calls);
   ``pin.abaInParallel`` on one thread over 64 states; MuJoCo's ``mj_step(m, d, nstep=1000)``
   with its Euler integrator (a step: ``mj_forward`` and the update). DART, Exudyn and Drake
   have no such loop reachable from Python: their row says so.
3. **batch** -- 64 states in one call, per state, on every core: the core's batch
   (``forward_dynamics(model, Q, V)``, default threads; and ``threads=1``),
   ``pin.abaInParallel`` on every core, MuJoCo's ``rollout`` of one step from each of the 64
   states on a pool of one thread per core.
4. **second** -- a whole simulated second at a stated accuracy: the scenario's motion over 1 s
   run by ``redysim compare``'s plan (:func:`redysim.reports.compare.plan`: the core with its
   integrators, every engine through ode45 and with each of its own integrators over a ladder
   of steps or tolerances; :func:`redysim.harness.sweep.run_sweep`, cached in
   ``results/bench/ladder/``), and per engine its cheapest run (CPU time of the integration,
   not wall time) whose observed path stays within ``--tol`` (1e-6 m) of the scenario's
   reference solution: the work per simulated second with the engine's best integrator here.

Rungs 1-3 are timed side by side: every callable of a system alternating within each round (the
order reversed every other round), a round a ``timeit`` loop of ~``--round-ms``; the median
per state over ``--rounds`` rounds is kept, and the fastest round. Writes ``--out`` (JSON: the
machine, the versions, the load average, one row per system, rung and engine); the report's
"Latency and throughput ladder" table reads it (``make bench-engines`` runs this).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from conftest import loop_of, machine, side_by_side

import redysim
from redysim import forward_dynamics, references
from redysim.algorithms._kernels import lean
from redysim.reports.build import ladder_core_reference
from redysim.reports.compare import engine_names

ROPE = str(Path(__file__).resolve().parents[1] / "cases" / "ladder" / "swing-U125-L1.toml")
SYSTEMS = {"xArm7": "XARM7-FALL", "Talos": "TALOS-FALL", "rope": ROPE}
BATCH = 64
LOOP = 1000       # calls (steps) per compiled loop
TOL = 1e-6        # m: the accuracy the last rung asks of the observed path over T_END
T_END = 1.0       # s
MJ_STEP_H = 1e-4  # s: MuJoCo's step in its nstep loop (the cost per step does not depend on it)
RUNG_NAMES = {1: "call", 2: "compiled", 3: "batch", 4: "second"}
NOT_REACHABLE = {  # rung 2 and 3 of the engines without a loop or a batch reachable from Python
    "dart": "no loop or batch of its dynamics callable from Python (World.step is one call a step)",
    "exudyn": "no loop or batch of its dynamics callable from Python (its solvers are rung 4)",
    "drake": "no loop or batch of MultibodyPlant's dynamics callable from Python (its Simulator "
             "is rung 4)",
}




def states(model, count: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``count`` seeded states near the neutral one: every joint coordinate that is not a free
    joint's quaternion moved by U(-0.3, 0.3), every velocity U(-0.3, 0.3)."""
    rng = np.random.default_rng(seed)
    quaternion = [i + j for i in model.quaternions for j in range(4)]
    plain = np.setdiff1d(np.arange(model.n_q), quaternion)
    Q = np.tile(model.neutral(), (count, 1))
    Q[:, plain] += rng.uniform(-0.3, 0.3, (count, plain.size))
    V = rng.uniform(-0.3, 0.3, (count, model.n_v))
    return Q, V


def core_calls(model, Q, V) -> dict:
    """The core's callables of rungs 1-3: name -> (rung, callable, states per call)."""
    q, v = Q[0], V[0]
    fd = redysim.evaluator(model)
    ws = redysim.Workspace(model)
    entry = (lean.FORWARD_CHAIN if ws.tree.serial else lean.FORWARD_TREE).compiled
    loop = loop_of(entry)
    out = np.empty(model.n_v)
    f, i, s, z = ws.kernel_f, ws.kernel_i, ws.scratch, ws.zeros
    ref = forward_dynamics(model, q, v)
    assert loop(q, v, z, out, f, i, s, 1).tobytes() == ref.tobytes()
    assert fd(q, v).tobytes() == ref.tobytes()
    OUT = np.empty_like(V)
    forward_dynamics(model, Q, V, out=OUT)  # the batch's compile and threads, not timed
    return {  # the first of each rung is the one the engines' rows are divided by
        "evaluator fd(q, v)": (1, lambda: fd(q, v), 1),
        "forward_dynamics(model, q, v)": (1, lambda: forward_dynamics(model, q, v), 1),
        f"kernel in a numba loop, x{LOOP}": (2, lambda: loop(q, v, z, out, f, i, s, LOOP), LOOP),
        f"forward_dynamics(model, Q, V), {BATCH} states":
            (3, lambda: forward_dynamics(model, Q, V, out=OUT), BATCH),
        "the same, threads=1": (3, lambda: forward_dynamics(model, Q, V, out=OUT, threads=1),
                                 BATCH),
    }


def engine_calls(name: str, eng, Q, V) -> dict:
    """An engine's callables of rungs 1-3 (``engines``' docstring): name -> (rung, callable,
    states per call), or name -> (rung, None, reason) for a rung it cannot run."""
    state, blocks = eng._state(Q[0], V[0])
    y = eng._to_engine(V[0], blocks)
    if name.startswith("pinocchio-aba"):
        pin, pm = eng.lib, eng.pm
        data, tau = pin.Data(pm), np.zeros(pm.nv)
        calls = {"pin.aba(model, data, q, v, tau)": (1, lambda: pin.aba(pm, data, state, y, tau),
                                                     1)}
    elif name == "mujoco":
        mj, m, d = eng.lib, eng.mjmodel, eng.mjdata

        def forward():
            d.qpos[:] = state
            d.qvel[:] = y
            mj.mj_forward(m, d)
            return d.qacc

        calls = {"qpos, qvel set; mj_forward(m, d)": (1, forward, 1)}
    else:
        calls = {"the adapter's own call": (1, lambda: eng._qdd(state, y, None), 1)}
    cores = os.cpu_count() or 1
    if name.startswith("pinocchio-aba"):
        cols = [eng._state(q, v) for q, v in zip(Q, V, strict=True)]
        PQ = np.asfortranarray(np.column_stack([qe for qe, _ in cols]))
        PV = np.asfortranarray(np.column_stack([eng._to_engine(v, blocks)
                                                for (_, blocks), v in zip(cols, V, strict=True)]))
        PT = np.zeros_like(PV)
        PA = np.zeros_like(PV)
        pool = pin.ModelPool(pm, cores)
        one = pin.aba(pm, pm.createData(), PQ[:, 0].copy(), PV[:, 0].copy(), PT[:, 0].copy())
        pin.abaInParallel(1, pool, PQ, PV, PT, PA)
        # the same computation (a different compiled path: 3e-12 apart on the xArm7, whose
        # small wrist links make its accelerations ~1e3 at these states)
        assert np.abs(PA[:, 0] - one).max() <= 1e-9 * np.abs(one).max()
        calls["pin.abaInParallel, 1 thread"] = (2, lambda: pin.abaInParallel(1, pool, PQ, PV, PT,
                                                                             PA), BATCH)
        calls[f"pin.abaInParallel, {cores} threads"] = (
            3, lambda: pin.abaInParallel(cores, pool, PQ, PV, PT, PA), BATCH)
    elif name == "mujoco":
        m.opt.integrator = int(mj.mjtIntegrator.mjINT_EULER)
        m.opt.timestep = MJ_STEP_H

        def steps():
            d.qpos[:] = state
            d.qvel[:] = y
            mj.mj_step(m, d, nstep=LOOP)

        calls[f"mj_step(m, d, nstep={LOOP}), Euler"] = (2, steps, LOOP)
        from mujoco import rollout

        spec = int(mj.mjtState.mjSTATE_FULLPHYSICS)
        init = np.empty((BATCH, mj.mj_stateSize(m, spec)))
        for k in range(BATCH):
            s_k, b_k = eng._state(Q[k], V[k])
            d.qpos[:] = s_k
            d.qvel[:] = eng._to_engine(V[k], b_k)
            mj.mj_getState(m, d, init[k], spec)
        datas = [mj.MjData(m) for _ in range(cores)]
        nstate = init.shape[1]
        buf = np.empty((BATCH, 1, nstate))
        sens = np.empty((BATCH, 1, m.nsensordata))
        rollout.rollout(m, datas, init, nstep=1, state=buf, sensordata=sens)
        calls[f"rollout, {BATCH} states x 1 step, {cores} threads"] = (
            3, lambda: rollout.rollout(m, datas, init, nstep=1, state=buf, sensordata=sens),
            BATCH)
    else:
        calls["compiled loop"] = (2, None, NOT_REACHABLE[name])
        calls["batch"] = (3, None, NOT_REACHABLE[name])
    return calls


def build_engine(name: str, model, q, v):
    """The engine's adapter on ``model`` with its qdd checked against the core's, or (None,
    reason)."""
    cls = references.get(name)
    if not cls.available():
        return None, f"package {cls.package!r} not installed"
    lim = cls.limits(model)
    if not lim.ok:
        return None, lim.reason
    eng = cls(model)
    ref = forward_dynamics(model, q, v)
    got = eng.qdd(q, v)
    diff = float(np.abs(got - ref).max() / np.abs(ref).max())
    if diff > 1e-8:
        return None, f"its qdd differs from the core's by {diff:.1e} (relative): not timed"
    return eng, ""


def timed_rows(label: str, scenario: str, rounds: int, round_s: float, log=print) -> list[dict]:
    """Rungs 1-3 of one system, side by side."""
    from redysim.io.scenarios import load_scenario

    model = load_scenario(scenario).model
    Q, V = states(model, BATCH)
    calls = {f"core: {k}": ("core", *c) for k, c in core_calls(model, Q, V).items()}
    versions = {"core": redysim.__version__}
    skipped = []
    for name in engine_names(model):
        eng, why = build_engine(name, model, Q[0], V[0])
        if eng is None:
            skipped.append({"system": label, "scenario": scenario, "dof": model.n_v, "rung": 1,
                            "engine": name, "call": "", "note": why})
            continue
        versions[name] = eng.version
        calls.update({f"{name}: {k}": (name, *c)
                      for k, c in engine_calls(name, eng, Q, V).items()})
    runnable = {k: c for k, c in calls.items() if c[2] is not None}
    log(f"ladder: {label} ({model.n_v} DOF): {len(runnable)} callables side by side, "
        f"{rounds} rounds")
    res = side_by_side({k: c[2] for k, c in runnable.items()}, rounds, round_s,
                       per={k: c[3] for k, c in runnable.items()})
    rows = skipped
    for k, (engine, rung, fn, per) in calls.items():
        row = {"system": label, "scenario": scenario, "dof": model.n_v, "rung": rung,
               "engine": engine, "version": versions[engine], "call": k.split(": ", 1)[1]}
        if fn is None:
            rows.append({**row, "note": per})
            continue
        r = res[k]
        rows.append({**row, "per_state_s": r["median_s"], "min_s": r["min_s"],
                     "ns_per_dof": r["median_s"] * 1e9 / model.n_v, "states_per_call": per,
                     "note": ""})
    return rows


def second_rows(label: str, scenario: str, out: Path, tol: float, log=print) -> list[dict]:
    """Rung 4 of one system: ``redysim compare``'s runs over T_END, the cheapest per engine
    within ``tol``."""
    from redysim.harness.spec import CORE
    from redysim.harness.sweep import run_sweep
    from redysim.io.scenarios import load_scenario
    from redysim.reports.compare import advice, plan, setting
    from redysim.reports.compare import label as run_label

    scn = load_scenario(scenario)
    sample = scn.sample_for(T_END)
    names = engine_names(scn.model)
    specs = plan(scenario, scn, options={}, t_end=T_END, sample=sample, engines=names)
    log(f"ladder: {label}: {len(specs)} runs over {T_END:g} s (cached in {out})")
    runs = run_sweep(specs, out, name=f"ladder-{scenario}", reference=True, progress=False)
    (adv,) = advice(runs, (tol,))
    ok = runs[runs["status"] == "ok"]
    rows = []
    for engine in [CORE, *names]:
        row = {"system": label, "scenario": scenario, "dof": scn.model.n_v, "rung": 4,
               "engine": "core" if engine == CORE else engine}
        best = adv["per_engine"].get(engine)
        if best is None:
            mine = ok[ok["engine"] == engine]
            least = (f"; its least error {float(mine['max_tip_err'].astype(float).min()):.1e} m"
                     if len(mine) else "")
            own = runs[runs["engine"] == engine]
            limited = int(own["reason"].astype(str).str.startswith("time limit").sum())
            cap = f", {limited} stopped at the CPU limit of a run" if limited else ""
            rows.append({**row, "call": "", "note": f"no run within {tol:g} m ({len(own)} runs"
                         f"{cap}{least})"})
            continue
        rows.append({**row, "call": f"{run_label(best).split(' ', 1)[1]} {setting(best)}",
                     "per_state_s": float(best["cpu_s"]) / T_END, "min_s": float("nan"),
                     "ns_per_dof": float(best["cpu_s"]) / T_END * 1e9 / scn.model.n_v,
                     "error_m": float(best["max_tip_err"]), "steps": int(best["steps"]),
                     "note": ""})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=21)
    ap.add_argument("--round-ms", type=float, default=20.0)
    ap.add_argument("--tol", type=float, default=TOL, help="rung 4's path tolerance [m]")
    ap.add_argument("--no-second", action="store_true", help="rungs 1-3 only")
    ap.add_argument("--runs", type=Path, default=Path("results/bench/ladder"),
                    help="rung 4's runs (a sweep folder per system, cached)")
    ap.add_argument("--out", type=Path, default=Path("results/bench/ladder.json"))
    args = ap.parse_args(argv)
    info = machine()
    load0 = os.getloadavg()
    started = time.strftime("%Y-%m-%d %H:%M")
    rows = []
    for label, scenario in SYSTEMS.items():
        rows += timed_rows(label, scenario, args.rounds, args.round_ms / 1e3)
    load1 = os.getloadavg()
    if not args.no_second:
        for label, scenario in SYSTEMS.items():
            rows += second_rows(label, scenario, args.runs / Path(scenario).stem, args.tol)
    core = ladder_core_reference(rows)
    for r in rows:
        if "per_state_s" in r and (r["system"], r["rung"]) in core:
            r["x_core"] = r["per_state_s"] / core[(r["system"], r["rung"])]
    print_table(rows)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"machine": info, "date": started, "tolerance_m": args.tol,
                                    "t_end_s": T_END, "batch": BATCH, "loop": LOOP,
                                    "load": [load0, load1], "rows": rows}, indent=1))
    print(f"written to {args.out}")
    return 0


def print_table(rows: list[dict]) -> None:
    print(f"{'system':7s} {'DOF':>4s} {'rung':9s} {'engine':14s} {'call':44s} "
          f"{'per state':>11s} {'ns/DOF':>9s} {'x core':>7s}")
    for r in rows:
        head = (f"{r['system']:7s} {r['dof']:4d} {RUNG_NAMES[r['rung']]:9s} {r['engine']:14s} "
                f"{r['call'][:44]:44s}")
        if "per_state_s" not in r:
            print(f"{head} {r['note'][:60]}")
            continue
        print(f"{head} {fmt(r['per_state_s']):>11s} {r['ns_per_dof']:9.0f} "
              f"{r.get('x_core', float('nan')):7.2f}")


def fmt(s: float) -> str:
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6)):
        if s >= scale:
            return f"{s / scale:.3g} {unit}"
    return f"{s * 1e9:.3g} ns"


if __name__ == "__main__":
    raise SystemExit(main())
