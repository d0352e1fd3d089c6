"""The default call against the call with a workspace: ``f(model, q, v)`` beside
``f(model, q, v, ws=ws)``, per call, for the public dynamics functions on robots and chains.

    .venv/bin/python benchmarks/default_path.py [--rounds 31] [--round-ms 10]

Models: UR5 and Talos (reduced, floating base) from example-robot-data when it is installed, the U
chains of 20 and 200 DOF (``Chain.uniform(n, "U", ...)``). Each (model, function) pair is timed side
by side in one process: rounds of ``timeit``-style loops (enough calls for ~``--round-ms`` a round),
the two calls alternating round by round, so that a neighbour's load falls on both. Prints each
call's median per-call time over the rounds, its fastest round, and the ratio of the medians
(default / ws: 1.00 means no overhead). A default call reuses the model's own workspace for the
calling thread (:func:`redysim.algorithms.workspace.model_workspace`); before that, it built one a
call. Writes ``results/bench/default_path.json``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
import timeit
from pathlib import Path

import numpy as np
from conftest import machine

import redysim
from redysim import Chain, Workspace

ROBOTS = {"UR5": ("ur_description/urdf/ur5_robot.urdf", False),
          "Talos (reduced, floating)": ("talos_reduced.urdf", True)}


def robot_path(file: str) -> str | None:
    from importlib import metadata

    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return None
    hits = [f for f in dist.files or () if str(f).endswith("/" + file)]
    return str(dist.locate_file(hits[0])) if hits else None


def models() -> dict:
    out = {}
    for label, (file, floating) in ROBOTS.items():
        path = robot_path(file)
        if path is None:
            print(f"(skipped {label}: example-robot-data is not installed)")
            continue
        out[label] = redysim.load_model(path, floating=floating, mimic="independent")
    for dof in (20, 200):
        out[f"U chain, {dof} DOF"] = Chain.uniform(
            dof // 2, "U", length=0.02, linear_density=7850 * np.pi * 0.05**2, radius=0.05,
            inertia="rod")
    return out


def state(model, seed=1):
    rng = np.random.default_rng(seed)
    q = model.neutral()
    quaternion = [i + j for i in model.quaternions for j in range(4)]
    plain = np.setdiff1d(np.arange(model.n_q), quaternion)
    q[plain] += rng.uniform(-0.3, 0.3, plain.size)
    return q, rng.uniform(-0.3, 0.3, model.n_v), rng.uniform(-0.3, 0.3, model.n_v)


def calls(model):
    """(name, call(ws=...)) for each public function timed."""
    q, v, a = state(model)
    frame = "tip" if "tip" in model.frames else model.body_names[-1]
    return [
        ("forward_dynamics", lambda **kw: redysim.forward_dynamics(model, q, v, **kw)),
        ("inverse_dynamics", lambda **kw: redysim.inverse_dynamics(model, q, v, a, **kw)),
        ("mass_matrix", lambda **kw: redysim.mass_matrix(model, q, **kw)),
        ("energy", lambda **kw: redysim.energy(model, q, v, **kw)),
        ("frame_motion", lambda **kw: redysim.frame_motion(model, q, v, a, frame=frame, **kw)),
    ]


def side_by_side(default, with_ws, rounds: int, round_s: float) -> dict:
    """Per-call seconds of each, alternating round by round: medians and minima over rounds."""
    timers = {"default": timeit.Timer(default), "ws": timeit.Timer(with_ws)}
    for t in timers.values():  # warm-up (compile or cache load; the model's workspace)
        t.timeit(3)
    number, _ = timers["ws"].autorange()
    t0 = time.perf_counter()
    timers["ws"].timeit(number)
    number = max(1, int(number * round_s / max(time.perf_counter() - t0, 1e-9)))
    per_call: dict[str, list[float]] = {k: [] for k in timers}
    for r in range(rounds):
        order = ("default", "ws") if r % 2 == 0 else ("ws", "default")
        for k in order:
            per_call[k].append(timers[k].timeit(number) / number)
    med = {k: statistics.median(v) for k, v in per_call.items()}
    return {"number": number, "rounds": rounds,
            **{f"{k}_median_s": med[k] for k in med},
            **{f"{k}_min_s": min(v) for k, v in per_call.items()},
            "ratio": med["default"] / med["ws"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=31)
    ap.add_argument("--round-ms", type=float, default=10.0)
    ap.add_argument("--out", type=Path, default=Path("results/bench/default_path.json"))
    args = ap.parse_args(argv)
    info = machine()
    print("default call vs ws= call, per call (median of rounds; fastest round in brackets)")
    print(", ".join(f"{k} {v}" for k, v in info.items()) + f", {time.strftime('%Y-%m-%d %H:%M')}")
    print(f"{'model':27s} {'function':17s} {'default us':>18s} {'ws= us':>18s} {'ratio':>6s}")
    rows = []
    for label, model in models().items():
        for name, call in calls(model):
            ws = Workspace(model)
            res = side_by_side(call, lambda call=call, ws=ws: call(ws=ws), args.rounds,
                               args.round_ms / 1e3)
            rows.append({"model": label, "function": name, **res})
            d = f"{res['default_median_s'] * 1e6:.2f} [{res['default_min_s'] * 1e6:.2f}]"
            w = f"{res['ws_median_s'] * 1e6:.2f} [{res['ws_min_s'] * 1e6:.2f}]"
            print(f"{label:27s} {name:17s} {d:>18s} {w:>18s} {res['ratio']:6.2f}", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"machine": info, "date": time.strftime("%Y-%m-%d %H:%M"),
                                    "rows": rows}, indent=1))
    worst = max(rows, key=lambda r: r["ratio"])
    print(f"worst ratio: {worst['ratio']:.2f} ({worst['model']}, {worst['function']})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
