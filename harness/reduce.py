"""Which joints a robot's scene needs: the joints that can be locked (their bodies fused) for a
tolerance on an observed frame's path, ranked by their measured effect and checked by running.

A reduction is :meth:`redysim.Model.locked`: the joint held at its value in the scenario's
initial state, its body fused into its parent (Pinocchio's ``buildReducedModel``). Its effect on
the scene is measured, not estimated: the reduced model is run from the scenario's initial state
(the locked joints' coordinates removed, and with them their velocities: a locked joint cannot
move, so the motion it carried goes with it) over the scenario's horizon by DOP853 at 1e-10, and
the observed frame's world position at every sample, computed on the full model with the locked
coordinates put back (the reduced model is the full one with those joints held: its bodies and
frames are the full model's, fused), is compared with the full model's run at the same setting.
The error is the largest distance over the samples.

:func:`reductions`:

1. every joint that can be locked (not a free joint, not coupled: ``Model.couplings``) locked
   alone: its error; the candidates ranked by it;
2. greedily, from the least effect up: a candidate joins the locked set when the set with it,
   run again, stays within the tolerance (effects do not add: each set is run, never summed);
   candidates whose own error exceeds the tolerance are not tried;
3. the full and the reduced model at a practical setting (ode45 at 1e-6): their CPU time, RHS
   calls and DOF, and the reduced model's error at that setting against the full model's
   reference run.

Every run is cached in ``out/reductions.json`` (keyed by the scenario's files, the code, the
locked set and the setting): asked again, nothing is run twice. A scenario file of the reduced
model (its locks, its initial state as explicit lists, the observed frame declared as a point
of the body it was fused into) is written beside it, so that the advice can be run by
``redysim simulate``.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from redysim.errors import SettingsError

REFERENCE = ("dop853", 1e-10)  # each model's path: the model's, not the integrator's error
PRACTICAL = ("ode45", 1e-6)    # where the full and the reduced model's costs are compared
RESULTS_FILE = "reductions.json"
SOURCE = "advise"


@dataclass
class Reduction:
    """What :func:`reductions` measured and advises (module docstring). ``candidates``: (joint,
    error [m]) ranked, least effect first; ``locked``: joint -> value(s) held; ``error``: the
    reduced model's path error at REFERENCE; ``practical``: {"full": {cpu_s, nfev, steps,
    cost_s, cost_repeats, cost_spread}, "reduced": {...}, "error": path error of the reduced
    model at PRACTICAL against the full model at REFERENCE, "verdict": the reduced model's cost
    against the full one's, "cheaper", "dearer" or "indistinguishable"
    (:func:`redysim.harness.cost.compare_two`)}; ``file``: the reduced scenario's file (None:
    the frame could not be declared on the reduced model, ``notes`` say why)."""

    scenario: str
    frame: str
    tol: float
    t_end: float
    full_dof: int
    reduced_dof: int
    candidates: list
    locked: dict
    error: float
    practical: dict
    file: Path | None
    notes: list = field(default_factory=list)
    file_check: float = math.nan  # the file run on its own: its path's distance from the advised


class _Runner:
    """The scene's runs, cached by (scenario files, code, locked set, setting)."""

    def __init__(self, scn, name: str, frame: str, t_end: float, sample: float, out: Path):
        from redysim.harness.provenance import code_digest
        from redysim.harness.spec import case_digest
        from redysim.harness.store import write_json_atomic

        self.scn, self.frame, self.t_end, self.sample = scn, frame, t_end, sample
        self.model = scn.model
        self.path = out / RESULTS_FILE
        self._write = write_json_atomic
        self.base = [case_digest(name), code_digest(), frame, t_end, sample]
        self.cache = json.loads(self.path.read_text()) if self.path.is_file() else {}
        self.q0, self.v0 = np.asarray(scn.q0, dtype=float), np.asarray(scn.v0, dtype=float)

    def values(self, joint: str) -> list[float]:
        """The joint's coordinates in the scenario's initial state."""
        m = self.model
        k = list(m.joint_names).index(joint)
        return [float(x) for x in self.q0[m.joint_qoff[k]:m.joint_qoff[k + 1]]]

    def reduced(self, locked: tuple[str, ...]):
        """(reduced model, kept q indices, kept v indices) with ``locked`` held at their initial
        values."""
        m = self.model
        drop_q, drop_v = [], []
        for name in locked:
            k = list(m.joint_names).index(name)
            drop_q += range(m.joint_qoff[k], m.joint_qoff[k + 1])
            drop_v += range(m.joint_voff[k], m.joint_voff[k + 1])
        keep_q = np.setdiff1d(np.arange(m.n_q), drop_q)
        keep_v = np.setdiff1d(np.arange(m.n_v), drop_v)
        red = m.locked({name: self.values(name) for name in locked}) if locked else m
        if (red.n_q, red.n_v) != (keep_q.size, keep_v.size):
            raise AssertionError(f"locking {locked} left {red.n_q}, {red.n_v} coordinates, "
                                 f"not {keep_q.size}, {keep_v.size}")
        return red, keep_q, keep_v

    def run(self, locked: tuple[str, ...], setting: tuple[str, float], *,
            timed: bool = False) -> dict:
        """The path of the scene's frame with ``locked`` held, at ``setting``: cached.
        ``timed``: its cost measured too (:mod:`redysim.harness.cost`: a short run repeated,
        the least of the repeats' CPU, the sampling excluded): ``cost_s``, ``cost_repeats``,
        ``cost_spread`` in the entry."""
        locked = tuple(sorted(locked))
        key = hashlib.sha256(json.dumps([*self.base, list(locked), list(setting)])
                             .encode()).hexdigest()[:16]
        if key in self.cache and (not timed or "cost_s" in self.cache[key]):
            return self.cache[key]
        from redysim.algorithms.dynamics import frame_motion
        from redysim.simulation import simulator

        full, frame = self.model, self.frame
        red, keep_q, keep_v = self.reduced(locked)
        qf, vf = self.q0.copy(), np.zeros(full.n_v)

        def observe(s):
            qf[keep_q] = s.q
            vf[keep_v] = s.v
            return frame_motion(full, qf, vf, frame=frame).position

        integrator, rtol = setting

        def new_sim():
            return simulator(red, self.t_end, q0=self.q0[keep_q], v0=self.v0[keep_v],
                             integrator=integrator, rtol=rtol, atol=rtol * 1e-2,
                             sample=self.sample, observe={"frame": observe}, keep_states=False,
                             damping=self.scn.damping)
        res = new_sim().run(clock="process", time_samples=timed)
        if res.status != 0:
            raise SettingsError(SOURCE, "SCENE", self.scn.name, f"the run with {list(locked)} "
                                f"locked failed: {res.message}")
        entry = {"locked": list(locked), "setting": list(setting),
                 "path": np.asarray(res.observed["frame"]).tolist(), "cpu_s": res.cpu_s,
                 "nfev": int(res.nfev), "steps": int(res.steps), "dof": int(red.n_v)}
        if timed:
            from . import cost

            def once() -> float:
                again = new_sim().run(clock="process", time_samples=True)
                return (again.cpu_s - again.sample_cpu_s if again.nfev == res.nfev
                        else math.nan)
            entry.update(cost.summary(cost.repeat(once, res.cpu_s - res.sample_cpu_s)))
        self.cache[key] = entry
        self._write(self.cache, self.path)  # each run kept as it finishes
        return entry


def _distance(a: dict, b: dict) -> float:
    return float(np.linalg.norm(np.asarray(a["path"]) - np.asarray(b["path"]), axis=1).max())


def reductions(scenario: str, tol: float, out: str | Path, *, frame: str | None = None,
               t_end: float = 0.0, log=print) -> Reduction:
    """The joints the scene can do without for a path tolerance ``tol`` [m] on ``frame`` (the
    scenario's observed frame by default), measured (module docstring)."""
    from redysim.io.scenarios import load_scenario

    if isinstance(tol, bool) or not isinstance(tol, int | float) or not (
            tol > 0 and math.isfinite(tol)):
        raise SettingsError(SOURCE, "--tip-tol", tol, "must be a path tolerance > 0 [m]")
    scn = load_scenario(scenario)
    model = scn.model
    if model.cuts:
        raise SettingsError(SOURCE, "SCENE", scn.name, "a closed mechanism: locking a joint of "
                            "its tree changes its loops; reductions are for open trees")
    frame = frame or scn.frame
    names = set(model.frames) | set(model.body_names)
    if frame not in names:
        raise SettingsError(SOURCE, "--observe", frame, f"no such frame or body in "
                            f"{scn.name}; its frames: {', '.join(sorted(model.frames)) or 'none'}"
                            f"; bodies: {', '.join(model.body_names[:12])}"
                            + (", ..." if model.n_bodies > 12 else ""))
    horizon = float(t_end or scn.t_end)
    sample = scn.sample_for(horizon)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    runner = _Runner(scn, scenario, frame, horizon, sample, out)
    coupled = {n for c in model.couplings for n in (c.follower, c.leader)}
    candidates = [name for name, kind in zip(model.joint_names, model.joint_types, strict=True)
                  if kind not in ("free", "fixed") and name not in coupled]
    if not candidates:
        raise SettingsError(SOURCE, "SCENE", scn.name, "has no joint to lock (free joints and "
                            "coupled joints are not locked)")
    log(f"advise: {scn.name}: {model.n_v} DOF, {len(candidates)} joints to try, the path of "
        f"{frame!r} over {horizon:g} s ({REFERENCE[0]} {REFERENCE[1]:g}); cached in "
        f"{runner.path}")
    ref = runner.run((), REFERENCE)
    ranked = []
    for i, name in enumerate(candidates, 1):
        ranked.append((name, _distance(runner.run((name,), REFERENCE), ref)))
        if i % 8 == 0 or i == len(candidates):
            log(f"advise: {i} of {len(candidates)} joints locked alone")
    ranked.sort(key=lambda x: (x[1], x[0]))
    locked: tuple[str, ...] = ()
    error = 0.0
    for name, alone in ranked:
        if alone > tol:
            break
        trial = runner.run((*locked, name), REFERENCE)
        e = _distance(trial, ref)
        if e <= tol:
            locked, error = (*locked, name), e
    log(f"advise: {len(locked)} joints locked together within {tol:g} m; comparing costs at "
        f"{PRACTICAL[0]} {PRACTICAL[1]:g}")
    from .cost import compare_two, cost_of

    full_p = runner.run((), PRACTICAL, timed=True)
    red_p = runner.run(locked, PRACTICAL, timed=True)
    keys = ("cpu_s", "nfev", "steps", "dof", "cost_s", "cost_repeats", "cost_spread")
    practical = {"full": {k: full_p[k] for k in keys},
                 "reduced": {k: red_p[k] for k in keys},
                 "error": _distance(red_p, ref), "full_error": _distance(full_p, ref),
                 # the reduced model's cost against the full one's: "cheaper", "dearer" or
                 # "indistinguishable" (their cost intervals overlap: within the noise)
                 "verdict": compare_two(cost_of(red_p), cost_of(full_p))}
    values = {name: runner.values(name) for name in locked}
    red_model = runner.reduced(locked)[0]
    result = Reduction(scn.name, frame, float(tol), horizon, model.n_v, red_model.n_v, ranked,
                       values, error, practical, None)
    if locked:
        result.file = write_reduced(scenario, scn, runner, locked, tol, out,
                                    result.notes)
    if result.file is not None:
        result.file_check = _file_check(result.file, runner.run(locked, REFERENCE))
    return result


def _file_check(path: Path, advised: dict) -> float:
    """The reduced scenario file run on its own (loaded as any scenario, its observed point
    from its own [observe] table) at REFERENCE: the largest distance of its path from the
    advised reduced run's."""
    from redysim.io.scenarios import load_scenario
    from redysim.simulation import frame_observer, simulator

    scn = load_scenario(path)
    sim = simulator(scn.model, scn.t_end, q0=scn.q0, v0=scn.v0, integrator=REFERENCE[0],
                    rtol=REFERENCE[1], atol=REFERENCE[1] * 1e-2, sample=scn.sample_interval,
                    observe={"frame": frame_observer(scn.model, scn.frame)}, keep_states=False,
                    damping=scn.damping)
    res = sim.run()
    got = np.asarray(res.observed["frame"])[:, :3]
    return float(np.linalg.norm(got - np.asarray(advised["path"]), axis=1).max())


def _anchor(model, locked: tuple[str, ...], frame: str, q) -> tuple[str, list[float]] | None:
    """The body the frame's point ends up on when ``locked`` are held (its nearest ancestor
    whose joint is not locked; None: the world), and the point in that body's frame, at q."""
    from redysim.algorithms.rbda import kinematics

    names = list(model.body_names)
    if frame in model.frames:
        body, point = model.frames[frame]
    else:
        body, point = names.index(frame), (0.0, 0.0, 0.0)
    kin = kinematics(model, q, np.zeros(model.n_v))
    x = kin.O[body] + kin.R[body] @ np.asarray(point, dtype=float)
    held = set(locked)
    b = body
    while b >= 0 and model.joint_names[b] in held:
        b = int(model.parent[b])
    if b < 0:
        return None
    return names[b], [float(c) for c in kin.R[b].T @ (x - kin.O[b])]


def write_reduced(scenario: str, scn, runner: _Runner, locked: tuple[str, ...], tol: float,
                  out: Path, notes: list) -> Path | None:
    """The reduced model's scenario file, beside the cache: the original scenario with
    ``[model] lock``, the initial state as explicit lists of the reduced model's coordinates,
    and the observed frame declared as a point of the body it is fused into."""
    import tomli_w

    from redysim.io.cases import read_toml
    from redysim.io.kinds import ScenarioKind, kind_of
    from redysim.io.robots import PREFIX as ROBOT_DATA
    from redysim.io.scenarios import scenario_path

    path = scenario_path(scenario)
    if path is None:
        notes.append("the scenario is not a file: no reduced scenario file written")
        return None
    if isinstance(kind_of(path), ScenarioKind):
        doc, _ = read_toml(path)
    else:  # a model file by itself (it was read as TOML and refused): the reduced scenario
        # names it, a robot of example-robot-data by its name
        text = str(scenario)
        doc = {"model": {"file": text if text.startswith(ROBOT_DATA) else str(path.resolve())}}
    red, keep_q, keep_v = runner.reduced(locked)
    anchor = _anchor(scn.model, locked, runner.frame, runner.q0)
    if anchor is None:
        notes.append(f"{runner.frame!r} is welded to the world by the locked joints: no reduced "
                     "scenario file (its path would not move)")
        return None
    body, point = anchor
    name = f"{scn.name}-REDUCED"
    model_doc = dict(doc.get("model", {}))
    model_file = model_doc.get("file", "")
    if model_file and not str(model_file).startswith(ROBOT_DATA) \
            and not Path(model_file).is_absolute():
        model_doc["file"] = str((path.parent / model_file).resolve())
    model_doc["lock"] = {**model_doc.get("lock", {}),  # the scenario's own locks kept
                         **{n: (v[0] if len(v) == 1 else v) for n, v in
                            ((n, runner.values(n)) for n in locked)}}
    observed = runner.frame if runner.frame in red.body_names or runner.frame in red.frames \
        else "observed"
    new = {"scenario": {"name": name,
                        "description": f"{scn.name} with {len(locked)} joints locked at their "
                                       f"initial values (redysim advise: the path of "
                                       f"{runner.frame!r} within {tol:g} m)"},
           "model": model_doc,
           "initial": {"q": [float(x) for x in runner.q0[keep_q]],
                       "v": [float(x) for x in runner.v0[keep_v]]},
           "simulation": {"t_end": runner.t_end, "sample_interval": runner.sample},
           "observe": {"frames": [observed]}}
    if observed == "observed":
        new["observe"]["points"] = {"observed": {"body": body, "at": point}}
    target = out / f"{name}.toml"
    target.write_text(f"# Written by redysim advise: {scn.name} reduced ({', '.join(locked)} "
                      f"locked); its observed point {runner.frame!r} as 'observed'\n"
                      + tomli_w.dumps(new))
    return target
