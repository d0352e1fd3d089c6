"""One call from Python, small systems: ``redysim.evaluator`` beside ``pin.aba`` and
``redysim.forward_dynamics``, and the floor under them.

    .venv/bin/python benchmarks/lean_call.py [--rounds 41] [--round-ms 20]

Models: a U chain of 20 DOF (``Chain.uniform(10, "U", ...)``: 10 links, two axes a joint; the RE-U
steel rod of ``benchmarks/test_bench_engines.py``), the UR5 of example-robot-data (its URDF read
by ``redysim.load_model``, Pinocchio's model built from the same file), the U chain of 200 DOF,
and the talk's PUMA 560 and Stanford arm (``cases/robots/``: DH tables, so that the core runs its
DH kernels on them). Pinocchio's chains and DH robots are ``redysim.references``' (built from our
model: ``JointModelUniversal`` joints, or each joint's DH placement). Per model, timed
side by side in one process, the calls alternating within each round (the order reversed every
other round) so that a neighbour's load falls on all of them; each round a ``timeit`` loop of
~``--round-ms``; printed: the median per call over the rounds, the fastest round, and
``pin.aba``'s median over the call's (> 1: faster than ``pin.aba``):

    pin.aba                  pin.aba(model, data, q, v, tau), tau zeros
    fd(ws=, out=)            forward_dynamics(model, q, v, ws=ws, out=out)
    fd default               forward_dynamics(model, q, v)
    evaluator                fd(q, v), fd = redysim.evaluator(model)
    evaluator out=           fd(q, v, out=out)
    floor: compiled call     the evaluator's lean entry through numba's compiled wrapper (its 7
                             arguments ready; what inverse_dynamics calls, and the evaluator
                             did before it was a builtin: redysim/algorithms/_kernels/binding.py)
    floor: kernel            the same function called 1,000 times from compiled code, per call
    evaluator, dh=False      (DH robots) fd(q, v) of ``redysim.evaluator(model, dh=False)``: the
                             general kernels on the same robot
    floor: kernel, dh=False  (DH robots) the general kernels' function, 1,000 calls from compiled
                             code, per call
    id evaluator, dh=False   (DH robots) the inverse's evaluator on the general kernels
    pin.rnea                 pin.rnea(model, data, q, v, qdd): inverse dynamics
    id default               inverse_dynamics(model, q, v, qdd)
    id evaluator             id(q, v, qdd), id = redysim.evaluator(model, "inverse_dynamics")
                             (these three rows: pin.rnea's median over the call's)

and once: a compiled function of 7 arrays that does nothing, called as the evaluator calls its
own, and a Python function of 4 arguments that does nothing. Writes
``results/bench/lean_call.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numba
import numpy as np
from conftest import loop_of, machine, side_by_side

import redysim
from redysim import Chain, Workspace, forward_dynamics, inverse_dynamics
from redysim._jit import LEAN_OPTIONS, unchecked_call
from redysim.algorithms._kernels import lean

UR5 = "ur_description/urdf/ur5_robot.urdf"
LOOP = 1000  # calls per loop of the compiled kernel


def robot_path(file: str) -> str:
    from importlib import metadata

    dist = metadata.distribution("example-robot-data")
    return str(dist.locate_file(next(f for f in dist.files or () if str(f).endswith("/" + file))))


def u_chain(dof: int) -> Chain:
    return Chain.uniform(dof // 2, "U", length=0.02, linear_density=61.6538, radius=0.05,
                         inertia="rod", name=f"U{dof // 2}")


def pinocchio_of(label: str, model):
    import pinocchio as pin

    if label == "UR5":
        return pin.buildModelFromUrdf(robot_path(UR5))
    from redysim.references.pinocchio_engine import PinocchioABA

    return PinocchioABA(model).pm


def _noop(q, v, tau, out, f, i, s):
    return out


def calls(label: str, model) -> dict:
    import pinocchio as pin

    rng = np.random.default_rng(1)
    q = model.neutral() + rng.uniform(-0.3, 0.3, model.n_q)
    v = rng.uniform(-0.3, 0.3, model.n_v)
    out = np.empty(model.n_v)
    ws = Workspace(model)
    fd = redysim.evaluator(model)
    assert fd(q, v).tobytes() == forward_dynamics(model, q, v).tobytes()
    pm = pinocchio_of(label, model)
    data = pm.createData()
    assert (pm.nq, pm.nv) == (model.n_q, model.n_v)  # (the same coordinates, in our order)
    pq, pv, ptau = q.copy(), v.copy(), np.zeros(pm.nv)
    aba = pin.aba
    entry = (lean.FORWARD_DH if ws.dh else lean.FORWARD_CHAIN if ws.tree.serial
             else lean.FORWARD_TREE).compiled
    raw = unchecked_call(entry)
    loop = loop_of(entry)
    f, i, s, z = ws.kernel_f, ws.kernel_i, ws.scratch, ws.zeros
    loop(q, v, z, out, f, i, s, 1)
    inv = redysim.evaluator(model, "inverse_dynamics")
    a = fd(q, v)
    assert inv(q, v, a).tobytes() == inverse_dynamics(model, q, v, a).tobytes()
    rnea, pa = pin.rnea, a.copy()
    general = {}
    if ws.dh:
        fd0, inv0 = redysim.evaluator(model, dh=False), redysim.evaluator(model, "inverse_dynamics",
                                                                          dh=False)
        loop0 = loop_of(lean.FORWARD_TREE.compiled)
        loop0(q, v, z, out, f, i, s, 1)
        general = {"evaluator, dh=False": lambda: fd0(q, v),
                   "floor: kernel, dh=False": lambda: loop0(q, v, z, out, f, i, s, LOOP),
                   "id evaluator, dh=False": lambda: inv0(q, v, a)}
    return {
        "pin.aba": lambda: aba(pm, data, pq, pv, ptau),
        "fd(ws=, out=)": lambda: forward_dynamics(model, q, v, ws=ws, out=out),
        "fd default": lambda: forward_dynamics(model, q, v),
        "evaluator": lambda: fd(q, v),
        "evaluator out=": lambda: fd(q, v, out=out),
        "floor: compiled call": lambda: raw(q, v, z, out, f, i, s),
        "floor: kernel": lambda: loop(q, v, z, out, f, i, s, LOOP),
        "pin.rnea": lambda: rnea(pm, data, pq, pv, pa),
        "id default": lambda: inverse_dynamics(model, q, v, a),
        "id evaluator": lambda: inv(q, v, a),
        **general,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=41)
    ap.add_argument("--round-ms", type=float, default=20.0)
    ap.add_argument("--out", type=Path, default=Path("results/bench/lean_call.json"))
    args = ap.parse_args(argv)
    import pinocchio as pin

    info = {**machine(), "pinocchio": pin.__version__}
    models = {"U chain, 20 DOF": u_chain(20), "UR5": redysim.load_model(robot_path(UR5)),
              "U chain, 200 DOF": u_chain(200),
              "PUMA 560 (DH)": redysim.load_model("cases/robots/puma560.toml"),
              "Stanford arm (DH)": redysim.load_model("cases/robots/stanford_arm.toml")}
    load0 = os.getloadavg()
    print("one call from Python: median of rounds [fastest round]; pin.aba's (pin.rnea's) median "
          "over the call's")
    print(", ".join(f"{k} {v}" for k, v in info.items()) + f", {time.strftime('%Y-%m-%d %H:%M')}")
    print(f"load average at start {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}; "
          f"{args.rounds} rounds of ~{args.round_ms:g} ms a call")
    rows = []
    print(f"{'model':18s} {'call':22s} {'us':>16s} {'pin / call':>11s}")
    for label, model in models.items():
        res = side_by_side(calls(label, model), args.rounds, args.round_ms / 1e3,
                           per={"floor: kernel": LOOP, "floor: kernel, dh=False": LOOP})
        for name, r in res.items():
            base = res["pin.rnea" if name.startswith(("pin.rnea", "id ")) else "pin.aba"]
            ratio = base["median_s"] / r["median_s"]
            rows.append({"model": label, "dof": model.n_v, "call": name, **r, "ratio": ratio})
            us = f"{r['median_s'] * 1e6:.3f} [{r['min_s'] * 1e6:.3f}]"
            print(f"{label:18s} {name:22s} {us:>16s} {ratio:11.2f}", flush=True)
    noop = numba.njit(lean.SIGNATURE, **dict(LEAN_OPTIONS, cache=False))(_noop)
    raw_noop = unchecked_call(noop)
    a = [np.zeros(8) for _ in range(7)]
    a[5] = np.zeros(8, dtype=np.int64)

    def py_noop(q, v, tau=None, out=None):
        return out

    floor = side_by_side({"compiled no-op, 7 arrays": lambda: raw_noop(*a),
                          "Python no-op, 2 arrays": lambda: py_noop(a[0], a[1]),
                          "empty lambda": lambda: None}, args.rounds, args.round_ms / 1e3)
    for name, r in floor.items():
        rows.append({"model": "-", "call": name, **r})
        us = f"{r['median_s'] * 1e6:.3f} [{r['min_s'] * 1e6:.3f}]"
        print(f"{'-':18s} {name:22s} {us:>16s}")
    load1 = os.getloadavg()
    print(f"load average at end {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"machine": info, "date": time.strftime("%Y-%m-%d %H:%M"),
                                    "load": [load0, load1], "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
