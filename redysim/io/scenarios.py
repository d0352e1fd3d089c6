"""Scenarios: a model, a state, a horizon and what to observe, as data: what every run, sweep,
reference solution and comparison takes.

A scenario is any of:

- a **scenario file**, a TOML file with a ``[scenario]`` table (``cases/scenarios/``; names
  without a folder, ``"UR5-FALL"``, are the built-in ones there)::

    [scenario]   name, description
    [model]      file: a model file of any kind (:mod:`redysim.io.kinds`: a .urdf, an MJCF
                 .xml, a DH robot, linkage or protein .toml, a rope case; a path relative to
                 the scenario file, a built-in case's name, or "example-robot-data:<file>" for
                 a URDF of that package); floating, mimic, equality (the loader's options, as
                 its kind takes them), lock = {joint = value}, gravity = [gx, gy, gz],
                 damping: a viscous torque -damping * v at every joint [N m s] (0: none; applied
                 by redysim's integrators whichever engine gives qdd; an engine's own stepper
                 refuses a damped scenario rather than run it undamped)
    [initial]    posture = "file" (default: the file's configuration) or "neutral"; q, v
                 (explicit lists, n_q and n_v long; v = 0 for rest); random = {seed, q, v}:
                 uniform perturbations of +-q [rad, m] of every joint coordinate that is not a
                 free joint's, and +-v of every velocity, from a seeded generator; a linkage
                 of one degree of freedom: driver_v, its driver's velocity (the others follow
                 from the loops)
    [simulation] t_end, sample_interval, integrator, rtol, atol, h
    [observe]    frames = [...]: frames of the model (``Model.frames``; a linkage's named points,
                 "coupler.P"; an MJCF file's sites), body names (their origins as the file
                 defines them), or points named here, points =
                 {name = {body = "...", at = [x, y, z]}} (a point of a body's frame [m]); the
                 first is the observed path that runs compare (the rope's "tip")

- a **rope case** (a name of ``cases/`` or a case file; :mod:`redysim.io.cases`), whose observed
  path is its tip and whose tip force is applied;
- a **model file** by itself (any kind of :mod:`redysim.io.kinds`: .urdf, MJCF .xml, DH robot,
  linkage or protein .toml): a passive motion from the file's configuration at rest for 1 s (a
  floating base or a model without gravity: with seeded random velocities, since at rest in
  uniform gravity it would fall as one rigid piece, and without gravity not move), observing its
  tip frame or its last body.

What kind a file is, and how its model is read with the loader's options, is its kind's
(:mod:`redysim.io.kinds`); this module reads scenario files and makes the scenario of the others.

:func:`load_scenario` reads any of them into a :class:`Scenario`. Every bad value raises
:class:`~redysim.errors.CaseError` naming the file, the field and the value; a model file's own
errors are its loader's (:class:`~redysim.errors.ModelFileError`). ``Scenario.digest`` hashes
every byte that defines it (the scenario file, the model file, the options), so that a result
computed from another version of either is never reused.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from redysim.errors import CaseError
from redysim.integrators.explicit import (
    DEFAULT_ATOL,
    DEFAULT_METHOD,
    DEFAULT_RTOL,
    FIXED_STEP,
    canonical,
    check_settings,
)
from redysim.io.cases import (
    CASES_DIR,
    FILE_SAMPLES,
    Case,
    file_simulator,
    is_case_name,
    read_toml,
)
from redysim.io.kinds import KINDS, Loaded, ScenarioKind, by_suffix, either, kind_of
from redysim.io.robots import PREFIX, package_hint, robot_file
from redysim.model.tree import FREE, QUATERNION_JOINTS, Model

SCENARIOS_DIR = Path(CASES_DIR) / "scenarios"
ROBOT_DATA = PREFIX  # a model file of the example-robot-data package (redysim.io.robots)
DEFAULT_T_END = 1.0  # s: a model file's own scenario
QUATERNION_TOL = 1e-6
_FIELDS = {
    "scenario": {"name", "description"},
    "model": {"file", "floating", "mimic", "equality", "lock", "gravity", "damping"},
    "initial": {"posture", "q", "v", "random", "driver_v"},
    "simulation": {"t_end", "sample_interval", "integrator", "rtol", "atol", "h"},
    "observe": {"frames", "points"},
}
MODEL_OPTIONS = ("floating", "mimic", "equality", "lock")
# a floating or weightless model file's own scenario: seeded random velocities of this amplitude
# [rad/s, m/s]
FLOATING_SEED, FLOATING_V = 20261127, 0.5


@dataclass(frozen=True, eq=False)
class Scenario:
    """A loaded scenario (module docstring): ``model`` (a :class:`redysim.Model`, with its cut
    joints for a linkage), the initial state ``q0``, ``v0``, the horizon and run settings,
    ``observe`` (frame or body names; the first is the observed path) and ``digest``.

    ``kind``: the name of the kind of file the model came from (``"urdf"``, ``"case"``, ...:
    :data:`redysim.io.kinds.KINDS`); ``case``: the rope case (None for any other kind), whose
    chain is ``model``, and which carries what only a rope has (its tip force, its coarsenings,
    its paper rows); ``tip_force``: the case's constant tip force [N] or None.
    ``options``: the model loader's options as given (floating, mimic, equality, lock)."""

    name: str
    path: Path | None
    kind: str
    model: Model
    q0: np.ndarray
    v0: np.ndarray
    t_end: float
    observe: tuple[str, ...]
    integrator: str = DEFAULT_METHOD
    rtol: float = DEFAULT_RTOL
    atol: float = DEFAULT_ATOL
    h: float | None = None
    sample_interval: float = 0.0  # 0: the run's horizon / FILE_SAMPLES (sample_for)
    description: str = ""
    digest: str = ""
    case: Case | None = None
    tip_force: np.ndarray | None = None
    options: dict[str, Any] = field(default_factory=dict)
    model_file: Path | None = None
    damping: float = 0.0  # N m s: a viscous torque -damping * v at every joint

    @property
    def chain(self) -> Model:
        """The model (a rope case's chain): the name the rope's harness has always used."""
        return self.model

    @property
    def momentum_kept(self) -> bool:
        """Whether the angular momentum about the centre of mass is constant: a floating system
        (a free root joint) under no force but uniform gravity (no tip force, damping, loops or
        gravity compensation, an external force; the model's joint damping and springs are
        internal)."""
        m = self.model
        return bool(m.joint_types and m.joint_types[0] == FREE and self.tip_force is None
                    and not self.damping and not m.cuts and not np.any(m.gravcomp)
                    and not m.gravcomp_loads.shape[0])

    @property
    def frame(self) -> str:
        """The observed path's frame: the first of ``observe``."""
        return self.observe[0]

    def simulator(self, t_end: float | None = None, *, q0=None, v0=None, **settings):
        """A :class:`redysim.simulation.Simulator` of this scenario: its model from its initial
        state (or ``q0``, ``v0``), a rope's tip force applied, its settings and horizon unless
        ``t_end`` and ``settings`` give others (``settings``: the keywords of
        :func:`redysim.simulation.simulator`; an ``integrator`` given as an object, an
        engine's own stepper, takes its own settings)."""
        if self.damping and settings.get("damping") is None:
            settings["damping"] = self.damping
        if self.case is not None:  # its tip force and settings: the case's
            return self.case.simulator(t_end, q0=self.q0 if q0 is None else q0,
                                       v0=self.v0 if v0 is None else v0, **settings)
        t_end = t_end or self.t_end
        return file_simulator(self, self.model, t_end, self.sample_for(t_end),
                              q0=self.q0 if q0 is None else q0,
                              v0=self.v0 if v0 is None else v0,
                              source=str(self.path or self.name), settings=settings)

    def sample_for(self, horizon: float) -> float:
        """The sample interval [s] of a run of this scenario to ``horizon``: its file's, else
        horizon / FILE_SAMPLES, at most the horizon."""
        return min(self.sample_interval or horizon / FILE_SAMPLES, horizon)

    @classmethod
    def from_case(cls, case: Case) -> Scenario:
        """A rope case as a scenario: its chain, state, settings, tip force; observing its tip."""
        return cls(name=case.name, path=case.path, kind="case", model=case.chain, q0=case.q0,
                   v0=case.v0, t_end=case.t_end, observe=("tip",), integrator=case.integrator,
                   rtol=case.rtol, atol=case.atol, h=case.h,
                   sample_interval=case.sample_interval, description=case.description,
                   digest=case.digest, case=case, tip_force=case.tip_force)


# --------------------------------------------------------------------------- finding files
def list_scenarios(directory: Path = SCENARIOS_DIR) -> list[str]:
    """Names of the built-in scenario files (``cases/scenarios/``)."""
    return sorted(p.stem for p in Path(directory).glob("*.toml"))


def robot_data_file(name: str) -> Path | None:
    """A file of the ``example-robot-data`` package by its short name (``"ur5"``) or the end of
    its path (``"ur_description/urdf/ur5_robot.urdf"``; :mod:`redysim.io.robots`), or None when
    the package is not installed or has no such file (or two)."""
    try:
        return robot_file(name)
    except FileNotFoundError:
        return None


def scenario_path(name_or_path: str | os.PathLike) -> Path | None:
    """The file of a built-in scenario name (``cases/scenarios/NAME.toml``), or the path given
    when it is a file; None for a name that is no scenario (a rope case's, perhaps)."""
    text = os.fspath(name_or_path)
    if text.startswith(ROBOT_DATA):  # a robot of example-robot-data, by name
        return robot_file(text[len(ROBOT_DATA):])
    model_file = by_suffix(text)
    if is_case_name(text) and not model_file:
        p = SCENARIOS_DIR / f"{text}.toml"
        return p if p.is_file() else None
    p = Path(text)
    if model_file and not p.is_file():
        raise FileNotFoundError(f"model file {text!r} does not exist{package_hint(text)}")
    return p if p.is_file() else None


def source_files(name_or_path: str | os.PathLike) -> list[Path]:
    """Every file whose bytes define the scenario: the scenario (or case) file and, for a
    scenario file, its model file (without loading the model). Raises what a load would for a
    name or file that does not exist."""
    from redysim.io.cases import case_path

    p = scenario_path(name_or_path)
    if p is None:
        return [case_path(name_or_path)]
    st = p.stat()
    return list(_sources_of(str(p), st.st_size, st.st_mtime_ns, st.st_ino))


@functools.lru_cache(maxsize=1024)
def _sources_of(path: str, _size: int, _mtime_ns: int, _ino: int) -> tuple[Path, ...]:
    """:func:`source_files` of an existing file, kept per version of it (its size,
    modification time and inode): a sweep asks for every run's id several times, and finding
    the kind of a .toml and the model file it names parses it up to five times."""
    p = Path(path)
    if not isinstance(kind_of(p), ScenarioKind):  # only a scenario file names another file
        return (p,)
    doc, _ = read_toml(p)
    model = doc.get("model", {})
    out = [p]
    if isinstance(model, dict) and isinstance(model.get("file"), str):
        try:
            out.append(_model_file(str(p), p, model["file"]))
        except (CaseError, FileNotFoundError):
            pass
    return tuple(out)


def digest_of(name_or_path: str | os.PathLike, options: dict | None = None) -> str:
    """SHA-256 over every file that defines the scenario (:func:`source_files`) and the
    loader's options."""
    h = hashlib.sha256()
    for f in source_files(name_or_path):
        h.update(hashlib.sha256(f.read_bytes()).digest())
    h.update(json.dumps(options or {}, sort_keys=True).encode())
    return h.hexdigest()


def _model_file(source: str, scenario: Path, text: str) -> Path:
    """The model file a scenario names: example-robot-data's, a built-in case's, or a path
    relative to the scenario file."""
    if text.startswith(ROBOT_DATA):
        try:
            return robot_file(text[len(ROBOT_DATA):])
        except FileNotFoundError as exc:
            why = str(exc).removeprefix(f"model file {text!r}").lstrip(": ")
            raise CaseError(source, "model.file", text, why) from None
    if is_case_name(text) and (Path(CASES_DIR) / f"{text}.toml").is_file():
        return Path(CASES_DIR) / f"{text}.toml"
    p = Path(text)
    if not p.is_absolute():
        p = scenario.parent / p
    if not p.is_file():
        raise CaseError(source, "model.file", text, f"no such file ({p})")
    return p


# --------------------------------------------------------------------------- loading
def load_scenario(name_or_path: str | os.PathLike, *,
                  options: dict[str, Any] | None = None) -> Scenario:
    """A scenario by name (a built-in scenario of ``cases/scenarios/`` or a rope case of
    ``cases/``) or by the path of a scenario, case or model file (module docstring).
    ``options``: the model loader's options for a model file given by itself (floating,
    mimic, equality, lock); a scenario file sets its own."""
    options = dict(options or {})
    unknown = set(options) - set(MODEL_OPTIONS)
    if unknown:
        raise CaseError("load_scenario", "options", sorted(unknown),
                        f"unknown; known: {', '.join(MODEL_OPTIONS)}")
    p = scenario_path(name_or_path)
    given = name_or_path if p is None else p  # None: a rope case's name (kind_of), or a
    # missing file: the case loader's message
    source = str(given)
    kind = kind_of(given)
    if isinstance(kind, ScenarioKind):  # a scenario file: read here
        kind.check_options(source, options)
        return _from_file(Path(given))
    loaded = kind.load(given, options, source=source)
    if loaded.case is not None:  # a rope case: its own settings, tip force, digest
        return Scenario.from_case(loaded.case)
    path = Path(given)
    model = loaded.model
    q0 = model.initial() if loaded.q0 is None else loaded.q0
    v0 = np.zeros(model.n_v)
    description = f"a passive motion of {path.name} from its file's configuration, at rest"
    weightless = not np.any(model.gravity)
    if FREE in model.joint_types or weightless:  # at rest it would fall as one piece, or stay
        q0, v0 = _random(source, model, {"seed": FLOATING_SEED, "v": FLOATING_V}, q0, v0)
        description = (f"{path.name} "
                       f"{'moving freely' if weightless else 'tumbling in free fall'}"
                       f" from its file's configuration with seeded random velocities (uniform "
                       f"in +-{FLOATING_V:g}, seed {FLOATING_SEED}): at rest it would "
                       + ("not move (no gravity)" if weightless else "fall as one rigid piece"))
    for a in (q0, v0):
        a.flags.writeable = False
    return _finish(source, path, kind.name, model, q0, v0, {}, options, None,
                   name=model.name or path.stem, description=description)


def _from_file(path: Path) -> Scenario:
    source = str(path)
    doc, _ = read_toml(path)
    for key in doc:
        if key not in _FIELDS:
            raise CaseError(source, key, None, f"unknown table; known: {', '.join(_FIELDS)}")
    for key, allowed in _FIELDS.items():
        node = doc.get(key, {})
        if not isinstance(node, dict):
            raise CaseError(source, key, node, "must be a table")
        for name in node:
            if name not in allowed:
                raise CaseError(source, f"{key}.{name}", None,
                                f"unknown field; known: {', '.join(sorted(allowed))}")
    head, mdoc = doc.get("scenario", {}), doc.get("model", {})
    if "file" not in mdoc:
        models = [k.noun for k in KINDS if not isinstance(k, ScenarioKind)]
        raise CaseError(source, "model.file", None, f"missing: the model's file ({either(models)}"
                        "; a case by its name)")
    if not isinstance(mdoc["file"], str):
        raise CaseError(source, "model.file", mdoc["file"], "must be a string")
    mfile = _model_file(source, path, mdoc["file"])
    kind = kind_of(mfile)
    if isinstance(kind, ScenarioKind):
        raise CaseError(source, "model.file", mdoc["file"], "is a scenario file, not a model")
    options = {k: mdoc[k] for k in MODEL_OPTIONS if k in mdoc}
    loaded = kind.load(mfile, options, source=source)
    model = loaded.model
    if "gravity" in mdoc:
        g = _vector(source, "model.gravity", mdoc["gravity"], 3)
        model = _with_gravity(model, g)
    name = head.get("name", path.stem)
    if not isinstance(name, str) or not name:
        raise CaseError(source, "scenario.name", name, "must be a non-empty string")
    damping = mdoc.get("damping", 0.0)
    if isinstance(damping, bool) or not isinstance(damping, int | float) or \
            not (math.isfinite(damping) and damping >= 0):
        raise CaseError(source, "model.damping", damping, "must be a finite number >= 0: the "
                        "viscous torque -damping * v at every joint [N m s] (0: none)")
    model = _points(source, model, doc.get("observe", {}))
    idoc = doc.get("initial", {})
    q0, v0 = _initial(source, model, idoc, loaded)
    case = None
    if loaded.case is not None:  # the rope's harness (tip force, coarsening) runs this
        # scenario's chain
        from dataclasses import replace

        from redysim.model.tree import Chain

        assert isinstance(model, Chain)  # a case's chain, its gravity perhaps replaced
        case = replace(loaded.case, chain=model, q0=q0, v0=v0)
    return _finish(source, path, kind.name, model, q0, v0, doc, options, case, name=name,
                   description=str(head.get("description", "")), model_file=mfile,
                   damping=float(damping))


def _with_frames(model: Model, frames: dict) -> Model:
    from dataclasses import replace

    return replace(model, frames={**model.frames, **frames}) if frames else model


def _points(source: str, model: Model, odoc: dict) -> Model:
    """The model with the [observe] table's named points (``points = {name = {body, at}}``:
    a point ``at`` [m] in a body's frame) as frames."""
    spec = odoc.get("points", {})
    if not isinstance(spec, dict):
        raise CaseError(source, "observe.points", spec, "must be a table {name = {body = "
                        "\"...\", at = [x, y, z]}}")
    frames = {}
    for name, node in spec.items():
        where = f"observe.points.{name}"
        if not isinstance(node, dict) or set(node) != {"body", "at"}:
            raise CaseError(source, where, node, "must be a table {body = \"...\", at = [x, y, "
                            "z]}")
        if node["body"] not in model.body_names:
            raise CaseError(source, f"{where}.body", node["body"], "no such body; known: "
                            f"{', '.join(map(str, model.body_names))}")
        if name in model.frames or name in model.body_names:
            raise CaseError(source, where, None, "names a frame or body the model has already")
        at = _vector(source, f"{where}.at", node["at"], 3)
        frames[name] = (list(model.body_names).index(node["body"]), tuple(at.tolist()))
    return _with_frames(model, frames)


def _with_gravity(model: Model, g: np.ndarray) -> Model:
    from dataclasses import replace

    g = np.array(g, dtype=float)
    g.flags.writeable = False
    return replace(model, gravity=g)


def _vector(source, name, value, n) -> np.ndarray:
    if isinstance(value, bool) or not isinstance(value, list) or len(value) != n or any(
            isinstance(x, bool) or not isinstance(x, int | float) for x in value):
        raise CaseError(source, name, value, f"must be a list of {n} numbers")
    a = np.array(value, dtype=float)
    if not np.isfinite(a).all():
        raise CaseError(source, name, value, "must be finite")
    return a


def _initial(source: str, model: Model, idoc: dict, loaded: Loaded
             ) -> tuple[np.ndarray, np.ndarray]:
    """(q0, v0) from the [initial] table (module docstring), checked: lengths, finiteness,
    unit quaternions; a linkage's q0 its file's (assembled: ``loaded.q0``), and its v0 given or
    made from ``driver_v`` (:func:`_driver_velocity`)."""
    linkage_q0 = loaded.q0
    posture = idoc.get("posture", "file")
    if posture not in ("file", "neutral"):
        raise CaseError(source, "initial.posture", posture, "choose 'file' (the model file's "
                        "configuration) or 'neutral' (every joint at zero)")
    if "q" in idoc and "posture" in idoc:
        raise CaseError(source, "initial.posture", posture, "give a posture or q, not both")
    if linkage_q0 is not None:
        q0 = np.array(linkage_q0, dtype=float)
    else:
        q0 = model.initial() if posture == "file" else model.neutral()
    if "q" in idoc:
        q0 = _vector(source, "initial.q", idoc["q"], model.n_q)
    v = idoc.get("v", 0.0)
    if "driver_v" in idoc:
        if "v" in idoc:
            raise CaseError(source, "initial.driver_v", idoc["driver_v"], "give v or driver_v, "
                            "not both")
        v0 = _driver_velocity(source, model, loaded.driver, q0, idoc["driver_v"])
    elif isinstance(v, int | float) and not isinstance(v, bool) and v == 0:
        v0 = np.zeros(model.n_v)
    else:
        v0 = _vector(source, "initial.v", v, model.n_v)
    if "random" in idoc:
        q0, v0 = _random(source, model, idoc["random"], q0, v0)
    for k, t in enumerate(model.joint_types):
        if t in QUATERNION_JOINTS:
            i = int(model.joint_qoff[k]) + (3 if t == FREE else 0)
            norm = float(np.linalg.norm(q0[i:i + 4]))
            if abs(norm - 1.0) > QUATERNION_TOL:
                raise CaseError(source, f"initial.q[{i}:{i + 4}]", q0[i:i + 4].tolist(),
                                f"the quaternion (w, x, y, z) of joint "
                                f"{model.joint_names[k]!r} has norm {norm:.9g}: give a unit "
                                "quaternion")
            q0[i:i + 4] /= norm
    if model.cuts and linkage_q0 is not None and ("q" in idoc or "random" in idoc):
        raise CaseError(source, "initial", sorted(idoc), "a linkage's q0 is assembled from its "
                        "driver (its file's [initial] table); give v only")
    if model.couplings:  # followers on their leaders: set after a random perturbation, else
        # the state given must keep them
        from redysim.algorithms.dynamics import check_coupled
        from redysim.errors import StateError

        if "random" in idoc:
            q0, v0 = model.couple(q0, v0)
        for name, x in (("q", q0), ("v", v0)):
            try:
                check_coupled(model, name, x)
            except StateError as exc:
                raise CaseError(source, f"initial.{name}", None, str(exc)) from None
    for a in (q0, v0):
        a.flags.writeable = False
    return q0, v0


def _driver_velocity(source: str, model: Model, driver: int | None, q0, w) -> np.ndarray:
    """The velocities of a linkage's joints with its driver at ``w`` [rad/s, or m/s] and the
    loops kept (J v = 0): the least-squares solution of [J; e_driver] v = [0; w], exact for a
    mechanism the driver moves on its own (one degree of freedom); refused where the driver
    leaves the others free (more degrees of freedom) or cannot move (a structure)."""
    from redysim.algorithms.loops import ClosedLoops

    where = "initial.driver_v"
    if driver is None:
        raise CaseError(source, where, w, "needs a linkage file with an [initial] driver")
    if isinstance(w, bool) or not isinstance(w, int | float) or not math.isfinite(w):
        raise CaseError(source, where, w, "must be a finite number (the driver's velocity)")
    J = ClosedLoops(model, source=source).evaluate(q0, np.zeros(model.n_v))[1]
    e = np.zeros(model.n_v)
    e[driver] = 1.0
    A = np.vstack((J, e))
    b = np.zeros(A.shape[0])
    b[-1] = w
    s = np.linalg.svd(J, compute_uv=False)
    rank = int((s > s[0] * 1e-10).sum()) if s.size and s[0] > 0 else 0
    if model.n_v - rank != 1:
        raise CaseError(source, where, w, f"the linkage has {model.n_v - rank} degrees of "
                        "freedom here; driver_v sets a one-degree-of-freedom mechanism's (give "
                        f"all {model.n_v} velocities as v)")
    v0, *_ = np.linalg.lstsq(A, b, rcond=None)
    return v0


def _random(source, model: Model, spec, q0, v0) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(spec, dict) or set(spec) - {"seed", "q", "v"} or "seed" not in spec:
        raise CaseError(source, "initial.random", spec, "must be a table {seed = N, q = "
                        "amplitude, v = amplitude} (seed required)")
    seed = spec["seed"]
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise CaseError(source, "initial.random.seed", seed, "must be a whole number >= 0")
    amp = {}
    for key in ("q", "v"):
        a = spec.get(key, 0.0)
        if isinstance(a, bool) or not isinstance(a, int | float) or not (
                math.isfinite(a) and a >= 0):
            raise CaseError(source, f"initial.random.{key}", a, "must be a number >= 0")
        amp[key] = float(a)
    rng = np.random.default_rng(seed)
    q0, v0 = q0.copy(), v0.copy()
    free_q: set[int] = set()
    for k, t in enumerate(model.joint_types):
        if t in QUATERNION_JOINTS:  # (a quaternion is not perturbed coordinate-wise)
            free_q.update(range(int(model.joint_qoff[k]), int(model.joint_qoff[k + 1])))
    dq = rng.uniform(-1.0, 1.0, model.n_q) * amp["q"]
    for i in range(model.n_q):
        if i not in free_q:
            q0[i] += dq[i]
    v0 += rng.uniform(-1.0, 1.0, model.n_v) * amp["v"]
    return q0, v0


def _frames(source: str, model: Model, odoc: dict, *, default: tuple[str, ...]
            ) -> tuple[str, ...]:
    frames = odoc.get("frames", list(default))
    if not isinstance(frames, list) or not frames or any(not isinstance(f, str)
                                                          for f in frames):
        raise CaseError(source, "observe.frames", frames, "must be a non-empty list of frame "
                        "or body names")
    names = set(model.frames) | set(model.body_names)
    for f in frames:
        if f not in names:
            known = sorted(names)
            raise CaseError(source, "observe.frames", f, "no such frame or body in the model; "
                            f"known: {', '.join(known[:30])}{' ...' if len(known) > 30 else ''}")
    return tuple(frames)


def default_frame(model: Model) -> str:
    """The path a model's own scenario observes: its "tip" frame, else its last body."""
    if "tip" in model.frames:
        return "tip"
    return str(model.body_names[model.n_bodies - 1])


def _finish(source: str, path: Path, kind: str, model: Model, q0, v0, doc: dict, options,
            case, *, name: str, description: str, model_file: Path | None = None,
            damping: float = 0.0) -> Scenario:
    sim = doc.get("simulation", {})
    base = case
    t_end = sim.get("t_end", base.t_end if base is not None else DEFAULT_T_END)
    integrator = sim.get("integrator", base.integrator if base is not None else DEFAULT_METHOD)
    if not isinstance(integrator, str):
        raise CaseError(source, "simulation.integrator", integrator, "must be a string")
    integrator = canonical(integrator)
    fixed = integrator in FIXED_STEP
    rtol = sim.get("rtol", base.rtol if base is not None else DEFAULT_RTOL)
    atol = sim.get("atol", base.atol if base is not None else DEFAULT_ATOL)
    h = sim.get("h", base.h if base is not None else None)
    sample = sim.get("sample_interval", None)
    if sample is None:
        sample = base.sample_interval if base is not None and base.sample_interval else None
    check_settings(source, {k: f"simulation.{k}" for k in ("rtol", "atol", "h", "t_end")} |
                   {"sample": "simulation.sample_interval", "method": "simulation.integrator"},
                   method=integrator, rtol=None if fixed else rtol,
                   atol=None if fixed else atol, h=h, t_end=t_end, sample=sample,
                   error=CaseError)
    if fixed and h is None:
        raise CaseError(source, "simulation.h", None, f"missing: {integrator} is fixed-step")
    sample = float(sample) if sample is not None else 0.0  # 0: the run's horizon / 20
    observe = _frames(source, model, doc.get("observe", {}), default=(default_frame(model),))
    opts = {k: v for k, v in options.items() if v is not None}
    digest = digest_of(path, None if doc else opts)  # a scenario file holds its options
    return Scenario(name=name, path=path, kind=kind, model=model, q0=q0, v0=v0,
                    t_end=float(t_end), observe=observe, integrator=integrator,
                    rtol=float(rtol), atol=float(atol), h=None if h is None else float(h),
                    sample_interval=sample, description=description, digest=digest,
                    case=case, tip_force=None if case is None else case.tip_force,
                    options=opts, model_file=model_file or path, damping=damping)
