"""A coupled robot's forward dynamics against the same robot uncoupled, side by side.

    .venv/bin/python benchmarks/ab_couplings.py [--menagerie DIR] [--rounds 7] [--calls 2000]
                                                [--batch 256]

For each robot with mimic joints (the Menagerie Panda, whose two fingers are coupled, when
``DIR/franka_emika_panda/panda.xml`` exists (``--menagerie`` or ``$MENAGERIE``: a checkout of
mujoco_menagerie), else example-robot-data's Panda URDF; example-robot-data's Talos
``talos_full_v2.urdf``, 12 mimic joints in its grippers, on a free base) the coupled Model and
the same Model without its couplings (``model.tree``) are timed by turns, on one state that
keeps the couplings, per call through:

- ``forward_dynamics(model, q, v, tau, ws=ws, out=out)``: the public door's hot path;
- ``redysim.evaluator(model)``: the evaluator's builtin (``fd(q, v, tau, out)``);
- a batch of ``--batch`` states, ``forward_dynamics(model, Q, V, T, out=O, threads=1)``, per
  state (the uncoupled batch in SIMD tiles, as by default; ``simd=False`` too);
- the Simulator's compiled derivative (``redysim.algorithms._kernels.system.derivative``, the
  right-hand side a compiled run's steps call), through its dispatcher.

Each round times ``--calls`` calls a side, coupled and uncoupled alternating, and keeps each
side's fastest of 5 repetitions; the table gives the minimum over the rounds, per call in us, and
coupled / uncoupled. Also: the coupled result against today's reference formula (the
reduced-coordinate solve), as a sanity check.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # (the checkout's redysim; its cases where it is not installed)
os.environ.setdefault("REDYSIM_CASES", str(ROOT / "cases"))
import redysim  # noqa: E402
from redysim.algorithms._kernels import system as K  # noqa: E402
from redysim.io.scenarios import robot_data_file  # noqa: E402


def robots(menagerie: str | None) -> dict:
    """The coupled robots timed (name: Model)."""
    out = {}
    xml = Path(menagerie or os.environ.get("MENAGERIE", ".")) / "franka_emika_panda" / "panda.xml"
    if xml.is_file():
        out["Panda (Menagerie MJCF)"] = redysim.load_model(str(xml))
    else:
        urdf = robot_data_file("panda_description/urdf/panda.urdf")
        if urdf is not None:
            out["Panda (URDF)"] = redysim.load_model(urdf)
    talos = robot_data_file("talos_data/robots/talos_full_v2.urdf")
    if talos is not None:
        out["Talos full v2"] = redysim.load_model(talos, floating=True)
    return out


def state(model, seed: int):
    """A state on the couplings (random joint angles and rates, model.couple)."""
    rng = np.random.default_rng(seed)
    q = model.initial()
    moving = slice(7, None) if model.quaternions.size else slice(None)
    q[moving] += rng.uniform(-0.3, 0.3, q[moving].shape)
    v = rng.normal(scale=0.5, size=model.n_v)
    if model.couplings:
        q, v = model.couple(q, v)
    return np.ascontiguousarray(q), np.ascontiguousarray(v), rng.normal(size=model.n_v)


def per_call(fn, calls: int) -> float:
    """The fastest of 5 repetitions of ``calls`` calls, per call [us]."""
    best = np.inf
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        best = min(best, time.perf_counter() - t0)
    return best / calls * 1e6


def doors(model, batch: int):
    """name: (a call, the states it computes per call) for the model."""
    q, v, tau = state(model, 7)
    ws = redysim.Workspace(model)
    out = np.empty(model.n_v)
    fd = redysim.forward_dynamics
    res = {"forward_dynamics": (lambda: fd(model, q, v, tau, ws=ws, out=out), 1)}
    try:
        ev = redysim.evaluator(model)
        res["evaluator"] = (lambda: ev(q, v, tau, out), 1)
    except redysim.errors.FieldError:
        res["evaluator"] = None
    rows = [state(model, 100 + i) for i in range(batch)]
    Q, V, T = (np.ascontiguousarray(np.array([r[i] for r in rows])) for i in range(3))
    O = np.empty_like(V)
    res[f"batch {batch} (default)"] = (lambda: fd(model, Q, V, T, out=O, threads=1), batch)
    res[f"batch {batch}, simd=False"] = (
        lambda: fd(model, Q, V, T, out=O, threads=1, simd=False), batch)
    from redysim.algorithms.system import System

    system = System(model, method="rge-a")
    if system.kernel is not None:
        sd, extras = system.kernel
        y = np.concatenate((q, v))
        dy = np.empty_like(y)
        deriv = K.derivative
        res["System derivative"] = (lambda: deriv(sd, extras, 0.0, y, dy), 1)
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--menagerie", default=None, help="a mujoco_menagerie checkout")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--calls", type=int, default=2000)
    ap.add_argument("--batch", type=int, default=256)
    a = ap.parse_args()
    for name, model in robots(a.menagerie).items():
        plain = model.tree
        sides = {"coupled": doors(model, a.batch), "uncoupled": doors(plain, a.batch)}
        for d in sides.values():  # warm up (compiles)
            for door in d.values():
                if door is not None:
                    door[0]()
        q, v, tau = state(model, 7)
        qdd = redysim.forward_dynamics(model, q, v, tau)
        print(f"\n{name}: n_v = {model.n_v}, {len(model.couplings)} couplings; "
              f"times per state [us], min over {a.rounds} rounds of {a.calls} calls")
        print(f"  {'door':28s} {'coupled':>9s} {'uncoupled':>10s} {'ratio':>7s}")
        for door in sides["coupled"]:
            c, u = sides["coupled"][door], sides["uncoupled"].get(door)
            if c is None or u is None:
                print(f"  {door:28s} {'refused':>9s}")
                continue
            best = {"c": np.inf, "u": np.inf}
            for _ in range(a.rounds):
                for key, (fn, per) in (("c", c), ("u", u)):
                    calls = max(a.calls // per, 3)
                    best[key] = min(best[key], per_call(fn, calls) / per)
            print(f"  {door:28s} {best['c']:9.3f} {best['u']:10.3f} "
                  f"{best['c'] / best['u']:7.2f}")
        _, _, fv, lv, m, _ = model.coupling_index
        print(f"  (qdd's followers on their leaders: {np.abs(qdd[fv] - m * qdd[lv]).max():.1e})")


if __name__ == "__main__":
    main()
