"""Case files: a chain, its initial state and the paper's settings, as TOML data.

A case file has these tables (see ``cases/README.md`` for every field):

    [case]        name, description, paper = {tables = [...], row = "..."}
    [chain]       links = N with uniform link fields, or [[chain.link]] entries; joint; gravity
    [initial]     q and v (a number, a list, or {fill, set, unit}), or shape = "catenary"
    [simulation]  t_end, integrator, rtol, atol, sample_interval
    [load]        tip_force = [Fx, Fy, Fz]: a constant world-frame force [N] at the chain's tip
                  (optional; :mod:`redysim.algorithms.loads` gives its joint forces and potential)

Every bad value raises :class:`~redysim.errors.CaseError` naming the file, the field and the value.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from redysim.errors import CaseError
from redysim.integrators.explicit import (
    DEFAULT_ATOL,
    DEFAULT_METHOD,
    DEFAULT_RTOL,
    FIXED_STEP,
    MAX_FIXED_STEPS,
    check_settings,
)
from redysim.model.parts import Joint, Link, check_inertia, check_positive, check_vector
from redysim.model.shapes import catenary_angles
from redysim.model.tree import Chain, Model

# The case files and the paper's numbers ship as package data (the repository's cases/ and paper/
# folders, installed as redysim.case_files and redysim.paper); REDYSIM_CASES points elsewhere.
CASES_DIR = Path(os.environ.get("REDYSIM_CASES") or str(resources.files("redysim.case_files")))
PUBLISHED = Path(str(resources.files("redysim.paper"))) / "published.toml"
MAX_LINKS = 2_000_000  # 100,000-DOF cases are 50,000 links; 2e6 links is ~2 GB of workspace
# samples over a file's horizon when it gives no sample_interval (a run of redysim.simulate,
# with no file: redysim.simulation.DEFAULT_SAMPLES)
FILE_SAMPLES = 20
# A revolute joint's angle [rad] beyond which float64 resolves it no better than ~1e-10 rad
# (spacing(1e6) = 1.2e-10): larger initial angles are a unit slip, and at 1e16 an angle no
# longer moves under a step (the run then ends "ok" with the chain frozen).
MAX_ANGLE = 1e6
# The fastest motion a case asks for (fastest_motion), against its horizon: ode45 takes about ten
# steps per radian of it (measured on a pulled 4-link chain and on RE-U50000-L1000:
# docs/notes/2026-11-costs-in-the-code.md), and a run takes at most MAX_FIXED_STEPS
# (redysim.integrators.explicit's bound on a fixed-step run), so a case whose fastest motion turns
# through more than MAX_RADIANS over t_end (a tip force of 1e300 N: ~1e151 rad/s) is refused at the
# door instead of running for ever with its time to go counting centuries. The cases shipped reach
# 1.3e5 rad (RE-U15000-L300).
STEPS_PER_RADIAN = 10
MAX_RADIANS = MAX_FIXED_STEPS / STEPS_PER_RADIAN
# A tip mass this many times the lightest link's: the GIM's condition number grows in proportion
# to the ratio (a decade of it costs qdd a digit), so beyond 1e10 qdd keeps at most 6 of
# float64's 16 digits before the chain's own conditioning takes its share.
MAX_TIP_MASS_RATIO = 1e10
PLAUSIBLE_GRAVITY = 1e3  # m/s^2 (100 g): a stronger gravity is named as the cause, not a link
# Chain fields that describe the links of a uniform chain (links = N); with [[chain.link]]
# entries each link gives its own, and these would be ignored, so they are refused.
UNIFORM_ONLY = ("link_length", "total_length", "link_mass", "total_mass", "linear_density",
                "density", "radius", "inertia", "com")

_FIELDS = {
    "case": {"name", "description", "paper"},
    "chain": {"links", "joint", "axis", "link_length", "total_length", "link_mass", "total_mass",
              "linear_density", "density", "radius", "inertia", "com", "gravity", "link",
              "tip_mass"},
    "link": {"length", "mass", "radius", "inertia", "com", "joint", "axis"},
    "initial": {"q", "v", "shape", "dX"},
    "simulation": {"t_end", "integrator", "rtol", "atol", "h", "sample_interval", "note"},
    "load": {"tip_force"},
}
TOP_TABLES = {"case", "chain", "initial", "simulation", "load"}  # ("link" is chain.link's)


@dataclass(frozen=True, eq=False)
class Case:
    """A loaded case: the chain, its initial state, its run settings, and what the paper ran and
    published.

    ``integrator``, ``rtol``, ``atol``, ``h`` and ``sample_interval`` are the ``[simulation]``
    table's, or the defaults (ode45, 1e-4, 1e-6, no step, t_end / 20); ``simulation`` is the table
    as written. ``digest``: SHA-256 of the file's bytes (of the document, for a case built from a
    dict), so that results computed from another version of the file are never reused.
    ``tip_force``: the ``[load]`` table's constant world-frame force at the tip [N], read-only, or
    None without one (:func:`redysim.algorithms.loads.tip_force_torques` turns it into joint
    forces).
    """

    name: str
    path: Path
    chain: Chain
    q0: np.ndarray
    v0: np.ndarray
    t_end: float
    description: str = ""
    simulation: dict[str, Any] = field(default_factory=dict)
    paper_tables: tuple[str, ...] = ()
    paper_row: str | None = None
    integrator: str = DEFAULT_METHOD
    rtol: float = DEFAULT_RTOL
    atol: float = DEFAULT_ATOL
    h: float | None = None
    sample_interval: float = 0.0
    digest: str = ""
    tip_force: np.ndarray | None = None

    def published(self) -> dict[str, Any]:
        """The published.toml entries this case is compared with: {table: entry or matching row}."""
        data = load_published()
        out = {}
        for table in self.paper_tables:
            node = data
            for part in table.split("."):
                node = node[part]
            rows = node.get("rows") if isinstance(node, dict) else None
            if rows and self.paper_row is not None and any("case" in r for r in rows):
                match = [r for r in rows if r.get("case") == self.paper_row]
                out[table] = match[0] if match else node
            else:
                out[table] = node
        return out

    def simulator(self, t_end: float | None = None, *, q0=None, v0=None, **settings):
        """A :class:`redysim.simulation.Simulator` of this case: its chain from its initial
        state (or ``q0``, ``v0``), its ``[load]`` applied (the tip force's joint torques, and its
        potential counted in the energy), its ``[simulation]`` settings (integrator, rtol, atol,
        h, sample interval) and horizon unless ``t_end`` and ``settings`` give others.
        ``settings``: the keywords of :func:`redysim.simulation.simulator` (``observe``,
        ``qdd``, ``keep_states``, ...; an ``integrator`` given as an object, an engine's own
        stepper, takes its own settings)."""
        if self.tip_force is not None:  # (a tau given adds to it)
            settings.setdefault("tip_force", self.tip_force)
        return file_simulator(self, self.chain, t_end or self.t_end, self.sample_interval or None,
                              q0=self.q0 if q0 is None else q0,
                              v0=self.v0 if v0 is None else v0, source=str(self.path),
                              settings=settings)

    def __repr__(self) -> str:
        return f"Case({self.name!r}, {self.chain!r}, t_end={self.t_end})"


def file_simulator(own, model: Model, t_end: float, sample: float | None, *, q0, v0,
                   source: str, settings: dict):
    """A :class:`redysim.simulation.Simulator` of a case or scenario file's run: ``own`` the
    file's run settings (its ``integrator``, ``rtol``, ``atol``, ``h``), taken where
    ``settings`` (the keywords of :func:`redysim.simulation.simulator`) give none; another
    integrator named takes the defaults (an integrator given as an object, an engine's own
    stepper, takes its own settings)."""
    from redysim.simulation import simulator

    integrator = settings.pop("integrator", None) or own.integrator
    same = integrator == own.integrator
    defaults: dict[str, Any] = {"sample": sample}
    if not hasattr(integrator, "solver"):  # a name, not a stepper
        defaults.update(rtol=own.rtol if same else DEFAULT_RTOL,
                        atol=own.atol if same else DEFAULT_ATOL, h=own.h if same else None)
    for key, value in defaults.items():
        if settings.get(key) is None:
            settings[key] = value
    return simulator(model, t_end, q0=q0, v0=v0, integrator=integrator, source=source,
                     **settings)


def load_published(path: Path = PUBLISHED) -> dict[str, Any]:
    """The paper's published numbers (``paper/published.toml``)."""
    with open(path, "rb") as fh:
        return tomllib.load(fh)


def list_cases(directory: Path = CASES_DIR) -> list[str]:
    """Names of the case files in ``cases/``."""
    return sorted(p.stem for p in Path(directory).glob("*.toml"))


def is_case_name(name_or_path: str | os.PathLike) -> bool:
    """True for the name of a built-in case (no folder, no ``.toml``), False for a path."""
    text = os.fspath(name_or_path)
    return not (isinstance(name_or_path, os.PathLike) or text.endswith(".toml") or os.sep in text
                or (os.altsep is not None and os.altsep in text))


def case_path(name_or_path: str | os.PathLike) -> Path:
    """The file of a case: a name without a folder or ``.toml`` (``"RE-U125-L1"``) is a built-in
    case and nothing else, so a file of that name in the working directory never replaces it; a
    path (``cases/mine.toml``, ``./mine``) is that file. Raises FileNotFoundError or CaseError."""
    if not isinstance(name_or_path, str | os.PathLike):
        raise CaseError("load_case", "name_or_path", name_or_path,
                        "must be a case name (a string) or the path of a case file")
    text = os.fspath(name_or_path)
    if not isinstance(text, str) or not text.strip():
        raise CaseError("load_case", "name_or_path", text, "must not be empty: give a case name "
                        "or the path of a case file")
    if is_case_name(name_or_path):
        candidate = Path(CASES_DIR) / f"{text}.toml"
        if candidate.is_file():
            return candidate
        hint = (f"; the file {text!r} in this directory is not read as a case unless you give "
                f"its path, ./{text}" if Path(text).exists() else "")
        raise FileNotFoundError(f"no case named {text!r} in {CASES_DIR}{hint}; known cases: "
                                f"{', '.join(list_cases())}")
    p = Path(text)
    if p.is_dir():
        raise CaseError(str(p), "<file>", None, "is a folder, not a case file")
    if not p.is_file():
        raise FileNotFoundError(f"case file {text!r} does not exist")
    return p


def has_table(path: str | os.PathLike, table: str) -> bool:
    """True for a file with a ``[table]`` line (read as text: no full parse; False when it
    cannot be read): what kind of TOML file a path is, cheaply."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            return any(line.strip() == f"[{table}]" for line in fh)
    except OSError:
        return False


def read_toml(path: str | os.PathLike) -> tuple[dict, bytes]:
    """(document, raw bytes) of a UTF-8 TOML file (a case, robot or linkage file); its syntax
    errors and non-UTF-8 bytes as a CaseError naming the file."""
    src = str(path)
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
        return tomllib.loads(raw.decode("utf-8")), raw
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(src, "<toml syntax>", None, str(exc)) from None
    except UnicodeDecodeError as exc:  # these files are UTF-8 text
        raise CaseError(src, "<toml syntax>", None,
                        f"not UTF-8 text (byte {exc.object[exc.start]:#04x} at offset "
                        f"{exc.start})") from None


def load_case(name_or_path: str | os.PathLike) -> Case:
    """Load a case by name (``"RE-U125-L1"``, from ``cases/``) or by the path of a TOML file
    (see :func:`case_path`)."""
    path = case_path(name_or_path)
    doc, raw = read_toml(path)
    return case_from_dict(doc, source=str(path), path=path,
                          digest=hashlib.sha256(raw).hexdigest())


# --------------------------------------------------------------------------- parsing
def _table(doc, key, source, required=True) -> dict:
    if key not in doc:
        if required:
            raise CaseError(source, key, None, f"missing table [{key}]")
        return {}
    node = doc[key]
    if not isinstance(node, dict):
        raise CaseError(source, key, node, f"[{key}] must be a table")
    return node


def _no_unknown(node: dict, allowed: set, source: str, prefix: str) -> None:
    for k in node:
        if k not in allowed:
            raise CaseError(source, f"{prefix}.{k}", node[k],
                            f"unknown field; expected one of {', '.join(sorted(allowed))}")


def _require(node, key, source, prefix):
    if key not in node:
        raise CaseError(source, f"{prefix}.{key}", None, "missing field")
    return node[key]


def _int(source, name, value, lo, hi):
    if isinstance(value, bool) or not isinstance(value, int):
        raise CaseError(source, name, value, "must be an integer")
    if not lo <= value <= hi:
        raise CaseError(source, name, value, f"must be between {lo:,} and {hi:,}")
    return value


def _joint(source, prefix, spec, axis=None) -> Joint:
    if isinstance(spec, dict):
        _no_unknown(spec, {"type", "axis"}, source, prefix)
        axis = spec.get("axis", axis)
        spec = _require(spec, "type", source, prefix)
    if not isinstance(spec, str):
        raise CaseError(source, prefix, spec, "a joint is a type name such as 'U' or {type, axis}")
    joint = Joint(spec, tuple(axis) if isinstance(axis, list) else axis)
    joint.axes(source, prefix)  # validates type and axis
    return joint


def _one_of(node, keys, source, prefix):
    given = [k for k in keys if k in node]
    if len(given) != 1:
        raise CaseError(source, prefix + "." + "|".join(keys), {k: node[k] for k in given} or None,
                        f"give exactly one of {', '.join(keys)}")
    return given[0], node[given[0]]


def _culprit(factors: dict[str, tuple[float, float, int]], too_large: bool) -> tuple[str, float]:
    """Of the fields (name -> (value as given, value as used, power)) whose product overflowed
    (``too_large``) or underflowed, the one that did most: its name and value as given."""
    score = {k: p * math.log10(used) for k, (_, used, p) in factors.items() if used > 0}
    name = (max if too_large else min)(score, key=score.__getitem__)
    return name, factors[name][0]


@dataclass(frozen=True)
class FastestMotion:
    """An estimate of the fastest motion of a chain (:func:`fastest_motion`): ``omega`` [rad/s],
    its ``cause`` ("tip_force", "tip_mass", "weight": the chain's own, "rate": an initial rate,
    or the pull of the spin it gives), the ``link`` (index) that moves that fast or, for
    "rate", the DOF; ``tension`` [N], the pull assumed along the chain."""

    omega: float
    cause: str
    link: int
    tension: float


def fastest_motion(chain: Chain, tip_force=None, v=None, tip_mass: float = 0.0
                   ) -> FastestMotion:
    """How fast the chain can move, as an order of magnitude: the largest of its initial rates
    (a prismatic one over its link's length) and of the swing rates of its links under the
    largest pull along the chain, omega_k = sqrt(T l_k / I_k) (a pendulum of length l_k and
    inertia I_k about its joint, the smaller of the two across the link, in a field that pulls
    its end with T), with T = |tip force| + total mass x (|g| + spin^2 x chain length), an upper
    bound of the tension anywhere in the chain. ``tip_mass`` [kg]: the part of the last link's
    mass that is a tip mass (for naming the cause). O(n) arithmetic, no dynamics."""
    g = _norm(chain.gravity)
    n_dof = chain.n_dof
    v = np.zeros(n_dof) if v is None else np.abs(np.asarray(v, dtype=float))
    link_of_dof = np.repeat(np.arange(chain.n_links), np.diff(chain.joint_qoff))
    rates = v / np.where(chain.dof_kind == 0, 1.0, chain.length[link_of_dof])
    fastest_dof = int(np.argmax(rates)) if n_dof else 0
    spin = float(rates[fastest_dof]) if n_dof else 0.0
    with np.errstate(over="ignore", invalid="ignore"):
        mass = chain.total_mass
        pulls = {"tip_force": 0.0 if tip_force is None else _norm(tip_force),
                 "tip_mass": tip_mass * g, "weight": max(mass - tip_mass, 0.0) * g,
                 "rate": mass * spin * spin * float(chain.length.sum())}
        tension = sum(pulls.values())
        across = np.minimum(chain.inertia_O[:, 1, 1], chain.inertia_O[:, 2, 2])
        swing = np.where(across > 0, tension * chain.length / np.where(across > 0, across, 1.0),
                         0.0)
    k = int(np.argmax(swing))
    omega = math.sqrt(swing[k]) if math.isfinite(swing[k]) else math.inf
    if not omega > spin:
        return FastestMotion(spin, "rate", fastest_dof, tension)
    return FastestMotion(omega, max(pulls, key=pulls.__getitem__), k, tension)


def _norm(x) -> float:
    """|x| without overflow of the squares (|(0, 1e300, 0)| = 1e300, not inf)."""
    x = np.abs(np.asarray(x, dtype=float))
    big = float(x.max()) if x.size else 0.0
    return big * float(np.linalg.norm(x / big)) if 0 < big < math.inf else big


def _check_pace(source: str, chain: Chain, t_end: float, motion: FastestMotion, *, tip_force,
                tip_mass: float, v0, explicit: bool, length_field: tuple[str, float]) -> None:
    """Refuse a case whose fastest motion turns through more than MAX_RADIANS over t_end,
    naming the field that makes it so (``length_field``: the link length's, when the chain's
    own weight does it under a plausible gravity; ``explicit``: [[chain.link]] entries)."""
    turns = motion.omega * t_end
    if turns <= MAX_RADIANS:
        return
    k = motion.link
    value: float | list[float]
    if motion.cause == "rate":
        name, value = f"initial.v[{k}]", float(v0[k])
        why = "an initial rate of the chain"
    else:
        which = f"chain.link[{k}]" if explicit else "a link"
        why = (f"{which} ({chain.length[k]:.3g} m, {chain.mass[k]:.3g} kg) swinging under a "
               f"pull of {motion.tension:.3g} N")
        if motion.cause == "tip_force":
            name, value = "load.tip_force", [float(x) for x in tip_force]
        elif motion.cause == "tip_mass":
            name, value = "chain.tip_mass", tip_mass
        elif _norm(chain.gravity) > PLAUSIBLE_GRAVITY:
            name, value = "chain.gravity", [float(x) for x in chain.gravity]
        else:
            name, value = length_field
    raise CaseError(source, name, value,
                    f"the chain's fastest motion would be ~{motion.omega:.3g} rad/s ({why}): "
                    f"~{turns:.3g} rad over t_end = {t_end:g} s, more than the "
                    f"{MAX_RADIANS:.0e} a run can integrate (about {STEPS_PER_RADIAN} steps a "
                    f"radian, at most {MAX_FIXED_STEPS:.0e} steps)")


def _uniform_links(chain, source) -> tuple[list[Link], list[Joint]]:
    nl = _int(source, "chain.links", chain["links"], 1, MAX_LINKS)
    lkey, lval = _one_of(chain, ("link_length", "total_length"), source, "chain")
    lval = check_positive(source, f"chain.{lkey}", lval)
    length = lval if lkey == "link_length" else lval / nl
    if not math.isfinite(length * length):
        raise CaseError(source, f"chain.{lkey}", lval, "too large: the link inertia m l^2 / 12 "
                        "overflows")
    radius = check_positive(source, "chain.radius", chain.get("radius", 0.0), allow_zero=True)
    key, val = _one_of(chain, ("link_mass", "total_mass", "linear_density", "density"), source,
                       "chain")
    val = check_positive(source, f"chain.{key}", val)
    # the inputs of the link's mass, as (value given, value used, power)
    if key == "link_mass":
        mass, of_mass = val, {key: (val, val, 1)}
    elif key == "total_mass":
        mass, of_mass = val / nl, {key: (val, val / nl, 1)}
    elif key == "linear_density":
        mass, of_mass = val * length, {key: (val, val, 1), lkey: (lval, length, 1)}
    else:
        if radius == 0.0:
            raise CaseError(source, "chain.radius", radius, "density needs a radius > 0")
        mass = val * math.pi * radius * radius * length
        of_mass = {key: (val, val, 1), "radius": (radius, radius, 2), lkey: (lval, length, 1)}
    if not (math.isfinite(mass) and mass > 0):
        too_large = not math.isfinite(mass)
        name, given = _culprit(of_mass, too_large=too_large)
        raise CaseError(source, f"chain.{name}", given,
                        f"too {'large' if too_large else 'small'}: it gives a link mass of "
                        f"{mass!r} kg (length {length!r} m)")
    inertia = chain.get("inertia", "rod")
    if isinstance(inertia, str):  # a standard model: m l^2 / 12 and m r^2 / 2 must be finite
        big = max(mass * length * length, mass * radius * radius)
        if not math.isfinite(big):
            # the inputs of m l^2 (and m r^2): the mass's, and the length twice more
            of_inertia = {k: (g, u, p + 2 * (k == lkey)) for k, (g, u, p) in of_mass.items()}
            of_inertia.setdefault(lkey, (lval, length, 2))
            if radius > 0:
                of_inertia.setdefault("radius", (radius, radius, 2))
            name, given = _culprit(of_inertia, too_large=True)
            raise CaseError(source, f"chain.{name}", given,
                            f"too large: the link's inertia overflows (mass {mass:.6g} kg, "
                            f"length {length:.6g} m, radius {radius:.6g} m)")
    link = _link_inertia(source, "chain", length, mass, radius, inertia, chain.get("com"))
    joint = _joint(source, "chain.joint", _require(chain, "joint", source, "chain"),
                   chain.get("axis"))
    return [link] * nl, [joint] * nl


def _with_tip_mass(link: Link, tip_mass: float) -> Link:
    """``link`` carrying a point mass at its distal end (length, 0, 0): the two bodies' mass,
    centre of mass and inertia about it (the parallel-axis theorem for each)."""
    m, c = link.mass, np.array(link.com, dtype=float)
    end = np.array([link.length, 0.0, 0.0])
    total = m + tip_mass
    com = (m * c + tip_mass * end) / total
    eye = np.eye(3)

    def shift(mass, r):
        return mass * ((r @ r) * eye - np.outer(r, r))

    inertia = np.array(link.inertia, dtype=float) + shift(m, c - com) + shift(tip_mass, end - com)
    return Link(link.length, total, tuple(com), tuple(map(tuple, inertia)),
                physical=link.physical)


def _link_inertia(source, prefix, length, mass, radius, inertia, com) -> Link:
    if isinstance(inertia, str):
        link = Link.uniform(length, mass, radius, inertia, source=source, field_name=prefix)
    else:  # explicit: a rigid body's inertia (the triangle inequality)
        I_c = check_inertia(source, f"{prefix}.inertia", inertia, physical=True)
        link = Link(length, mass, (length / 2, 0.0, 0.0), tuple(map(tuple, I_c)))
    if com is not None:
        c = check_vector(source, f"{prefix}.com", com, 3)
        link = Link(link.length, link.mass, tuple(c), link.inertia, physical=link.physical)
    return link


def _explicit_links(chain, source) -> tuple[list[Link], list[Joint]]:
    entries = chain["link"]
    if not isinstance(entries, list) or not entries:
        raise CaseError(source, "chain.link", entries,
                        "must be a non-empty array of [[chain.link]]")
    if len(entries) > MAX_LINKS:
        raise CaseError(source, "chain.link", f"{len(entries)} entries", f"at most {MAX_LINKS:,}")
    for key in UNIFORM_ONLY:
        if key in chain:
            raise CaseError(source, f"chain.{key}", chain[key],
                            "applies to uniform chains (links = N) only; with [[chain.link]] "
                            "entries give it in each entry")
    if "links" in chain:
        nl = _int(source, "chain.links", chain["links"], 1, MAX_LINKS)
        if nl != len(entries):
            raise CaseError(source, "chain.links", nl,
                            f"disagrees with the {len(entries)} [[chain.link]] entries")
    links, joints = [], []
    for k, e in enumerate(entries):
        prefix = f"chain.link[{k}]"
        if not isinstance(e, dict):
            raise CaseError(source, prefix, e, "must be a table")
        _no_unknown(e, _FIELDS["link"], source, prefix)
        length = check_positive(source, f"{prefix}.length", _require(e, "length", source, prefix))
        mass = check_positive(source, f"{prefix}.mass", _require(e, "mass", source, prefix))
        radius = check_positive(source, f"{prefix}.radius", e.get("radius", 0.0), allow_zero=True)
        links.append(_link_inertia(source, prefix, length, mass, radius, e.get("inertia", "rod"),
                                   e.get("com")))
        jspec = e.get("joint", chain.get("joint"))
        if jspec is None:
            raise CaseError(source, f"{prefix}.joint", None, "missing field (and no chain.joint)")
        joints.append(_joint(source, f"{prefix}.joint", jspec, e.get("axis", chain.get("axis"))))
    return links, joints


def _vector_spec(spec, n, source, name) -> np.ndarray:
    """A state vector from a number (fill), a list, or {fill, set = [[i, x], ...], unit}."""
    unit = 1.0
    if isinstance(spec, dict):
        _no_unknown(spec, {"fill", "set", "unit", "values"}, source, name)
        if "values" in spec and "fill" in spec:
            raise CaseError(source, f"{name}.values|fill", None, "give values or fill, not both")
        u = spec.get("unit", "rad")
        if u not in ("rad", "deg"):
            raise CaseError(source, f"{name}.unit", u, "must be 'rad' or 'deg'")
        unit = math.pi / 180 if u == "deg" else 1.0
        if "values" in spec:
            out = check_vector(source, f"{name}.values", spec["values"], n)
        else:
            fill = spec.get("fill", 0.0)
            if (isinstance(fill, bool) or not isinstance(fill, int | float)
                    or not math.isfinite(fill)):
                raise CaseError(source, f"{name}.fill", fill, "must be a finite number")
            out = np.full(n, float(fill))
        entries = spec.get("set", [])
        if not isinstance(entries, list):
            raise CaseError(source, f"{name}.set", entries,
                            "must be a list of [dof_index, value] pairs")
        for i, item in enumerate(entries):
            if not (isinstance(item, list) and len(item) == 2):
                raise CaseError(source, f"{name}.set[{i}]", item, "must be [dof_index, value]")
            idx, x = item
            _int(source, f"{name}.set[{i}][0]", idx, 0, n - 1)
            if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
                raise CaseError(source, f"{name}.set[{i}][1]", x, "must be a finite number")
            out[idx] = x
        return out * unit
    if isinstance(spec, int | float) and not isinstance(spec, bool):
        if not math.isfinite(spec):
            raise CaseError(source, name, spec, "must be finite (no NaN or Inf)")
        return np.full(n, float(spec))
    if isinstance(spec, list):
        return check_vector(source, name, spec, n)
    raise CaseError(source, name, spec,
                    "must be a number, a list of n numbers or {fill, set, unit}")


def case_from_dict(doc: dict, *, source: str = "<dict>", path: Path | None = None,
                   digest: str | None = None) -> Case:
    """Build a :class:`Case` from a parsed TOML document (see the module docstring).

    ``digest``: the SHA-256 of the file the document was read from (:func:`load_case` gives
    it); by default, that of the document itself (its JSON, keys sorted)."""
    if not isinstance(doc, dict):
        raise CaseError(source, "<top>", type(doc).__name__, "a case is a table (a parsed TOML "
                        "document, a dict)")
    _no_unknown(doc, TOP_TABLES, source, "<top>")
    meta = _table(doc, "case", source)
    _no_unknown(meta, _FIELDS["case"], source, "case")
    name = _require(meta, "name", source, "case")
    if not isinstance(name, str) or not name:
        raise CaseError(source, "case.name", name, "must be a non-empty string")
    paper = meta.get("paper", {})
    if not isinstance(paper, dict):
        raise CaseError(source, "case.paper", paper, "must be a table {tables = [...], row = ...}")
    _no_unknown(paper, {"tables", "row"}, source, "case.paper")
    tables = paper.get("tables", [])
    if not (isinstance(tables, list) and all(isinstance(t, str) for t in tables)):
        raise CaseError(source, "case.paper.tables", tables,
                        "must be a list of published.toml entry names such as ['table2']")
    tables = tuple(tables)
    row = paper.get("row")
    if row is not None and not isinstance(row, str):
        raise CaseError(source, "case.paper.row", row, "must be a case name (a string)")
    published = load_published()
    for t in tables:
        node = published
        for part in str(t).split("."):
            if not isinstance(node, dict) or part not in node:
                raise CaseError(source, "case.paper.tables", t,
                                "no such entry in paper/published.toml")
            node = node[part]

    chain_t = _table(doc, "chain", source)
    _no_unknown(chain_t, _FIELDS["chain"], source, "chain")
    if "link" in chain_t:
        links, joints = _explicit_links(chain_t, source)
    elif "links" in chain_t:
        links, joints = _uniform_links(chain_t, source)
    else:
        raise CaseError(source, "chain.links", None,
                        "missing field: give links = N (uniform) or [[chain.link]] entries")
    tip_mass = 0.0
    if "tip_mass" in chain_t:
        tip_mass = check_positive(source, "chain.tip_mass", chain_t["tip_mass"])
        lightest = min(links[-1].mass, min(link.mass for link in links[:-1])
                       if "link" in chain_t and len(links) > 1 else links[0].mass)
        if tip_mass > MAX_TIP_MASS_RATIO * lightest:
            raise CaseError(source, "chain.tip_mass", chain_t["tip_mass"],
                            f"{tip_mass / lightest:.3g} times the lightest link's mass "
                            f"({lightest:.3g} kg), more than {MAX_TIP_MASS_RATIO:.0e}: the "
                            "GIM's condition number grows in proportion to that ratio (a "
                            "decade of it costs qdd a digit of float64's 16)")
        links[-1] = _with_tip_mass(links[-1], tip_mass)
    gravity = chain_t.get("gravity", [0.0, -9.81, 0.0])
    chain = Chain.build(links, joints, gravity=gravity, name=name, source=source)

    init = _table(doc, "initial", source, required=False)
    if "qd" in init:  # the name before one name per quantity
        raise CaseError(source, "initial.qd", init["qd"], "renamed initial.v (the generalized "
                        "velocity, as everywhere in redysim: for a free joint it is not dq/dt)")
    _no_unknown(init, _FIELDS["initial"], source, "initial")
    n = chain.n_dof
    if "shape" in init:
        if init["shape"] != "catenary":
            raise CaseError(source, "initial.shape", init["shape"], "known shapes: 'catenary'")
        if not chain.is_planar:
            raise CaseError(source, "initial.shape", "catenary", "needs a planar R chain")
        dX = check_positive(source, "initial.dX", _require(init, "dX", source, "initial"))
        total = float(chain.length.sum())
        if dX > total * (1 + 1e-12):
            raise CaseError(source, "initial.dX", dX, f"must not exceed the chain's length {total}")
        if not np.allclose(chain.length, chain.length[0]):
            raise CaseError(source, "initial.shape", "catenary", "needs links of equal length")
        if chain.n_links == 1 and dX < total * (1 - 1e-12):
            raise CaseError(source, "initial.dX", dX, f"a chain of one link spans only its own "
                            f"length {total}: a catenary start needs at least two links")
        try:
            q0 = catenary_angles(chain.n_links, total, min(dX, total))
        except ValueError:  # the root finder's bracket holds no catenary this flat
            raise CaseError(source, "initial.dX", dX,
                            f"too small: no catenary of arc length {total} spans it "
                            f"(dX / length = {dX / total:.3g})") from None
        if "q" in init:
            raise CaseError(source, "initial.q", init["q"], "give either shape or q, not both")
    else:
        q0 = _vector_spec(init.get("q", 0.0), n, source, "initial.q")
        angles = np.abs(q0) * (chain.dof_kind == 0)  # revolute DOFs only
        if angles.max() > MAX_ANGLE:
            j = int(np.argmax(angles))
            raise CaseError(source, f"initial.q[{j}]", float(q0[j]),
                            f"a joint angle beyond {MAX_ANGLE:g} rad is a unit slip: float64 "
                            f"resolves it only to {math.ulp(float(q0[j])):.3g} rad")
    v0 = _vector_spec(init.get("v", 0.0), n, source, "initial.v")

    sim = _table(doc, "simulation", source, required=False)
    _no_unknown(sim, _FIELDS["simulation"], source, "simulation")
    t_end = _require(sim, "t_end", source, "simulation")
    integrator = sim.get("integrator", DEFAULT_METHOD)
    fixed = integrator in FIXED_STEP
    names = {k: f"simulation.{k}" for k in ("integrator", "rtol", "atol", "h", "t_end")}
    names["sample"] = "simulation.sample_interval"
    check_settings(source, names, method=integrator, t_end=t_end,
                   rtol=sim.get("rtol"), atol=sim.get("atol"), h=sim.get("h"),
                   sample=sim.get("sample_interval"), error=CaseError)
    if fixed and "h" not in sim:
        raise CaseError(source, "simulation.h", None,
                        f"missing field: integrator {integrator!r} is fixed-step and needs h")
    if fixed and ("rtol" in sim or "atol" in sim):
        key = "rtol" if "rtol" in sim else "atol"
        raise CaseError(source, f"simulation.{key}", sim[key],
                        f"applies to adaptive integrators; {integrator!r} steps at h")
    t_end = float(t_end)

    load = _table(doc, "load", source, required=False)
    _no_unknown(load, _FIELDS["load"], source, "load")
    tip_force = None
    if "tip_force" in load:  # a copy: a dict's own array must stay as the caller left it
        tip_force = np.array(check_vector(source, "load.tip_force", load["tip_force"], 3))
        tip_force.flags.writeable = False
    motion = fastest_motion(chain, tip_force, v0, tip_mass)
    explicit = "link" in chain_t
    if explicit:
        length_field = (f"chain.link[{motion.link}].length",
                        chain_t["link"][motion.link].get("length"))
    else:
        lkey = "link_length" if "link_length" in chain_t else "total_length"
        length_field = (f"chain.{lkey}", chain_t[lkey])
    _check_pace(source, chain, t_end, motion, tip_force=tip_force, tip_mass=tip_mass, v0=v0,
                explicit=explicit, length_field=length_field)
    q0.flags.writeable = False
    v0.flags.writeable = False
    if digest is None:
        digest = hashlib.sha256(json.dumps(doc, sort_keys=True, default=repr).encode()).hexdigest()
    return Case(name=name, path=path or Path(source), chain=chain, q0=q0, v0=v0, t_end=t_end,
                description=str(meta.get("description", "")), simulation=dict(sim),
                paper_tables=tables, paper_row=row, integrator=integrator,
                rtol=float(sim.get("rtol", DEFAULT_RTOL)),
                atol=float(sim.get("atol", DEFAULT_ATOL)),
                h=float(sim["h"]) if "h" in sim else None,
                sample_interval=min(float(sim.get("sample_interval", t_end / FILE_SAMPLES)),
                                    t_end),
                digest=digest, tip_force=tip_force)


def rebuild_problem(case) -> str:
    """Why ``case`` cannot be rebuilt at another link count ("" when it can): the rope must come
    from a file with a uniform ``[chain] links = N`` and start straight (every relative angle and
    rate but the first joint's zero), so that the rope at any count is the same body in the same
    state. (Lumping such a rope's links, as :func:`redysim.coarsen` does, gives the rope rebuilt
    at the coarser count: each lumped link is the segment it replaces.)"""
    path = getattr(case, "path", None)
    if path is None or not Path(path).is_file():
        return "it has no case file to rebuild from"
    table = read_toml(path)[0].get("chain", {})
    if "links" not in table or "link" in table:
        return f"{path} does not give a uniform [chain] links = N (its links are listed)"
    chain = case.chain
    bent = max(float(np.abs(case.q0[int(chain.joint_qoff[1]):]).max(initial=0.0)),
               float(np.abs(case.v0[int(chain.joint_voff[1]):]).max(initial=0.0)))
    if bent:
        return (f"{path} starts bent or bending (relative angles or rates beyond the first "
                f"joint's, up to {bent:.3g}): at another count the rope's shape would differ")
    return ""


def rebuilt_case(case, links: int):
    """The rope of ``case`` (a straight rope's file: :func:`rebuild_problem`) rebuilt with
    ``links`` uniform links: the same material, length, radius and tip mass, the same initial
    state (its first joint's angle and rate). Raises CaseError naming the case when it cannot
    be rebuilt."""
    why = rebuild_problem(case)
    if why:
        raise CaseError(str(getattr(case, "path", case.name)), "links", links,
                        f"does not divide the case's {case.chain.n_links} links, and {why}")
    # the state as the rebuilt rope's: its first joint's coordinates and rates (a straight
    # rope's only nonzero ones), the rest zero; a list in the file has the old count's length
    chain = case.chain
    first = {name: {"fill": 0.0, "set": [[k, float(x[k])] for k in range(int(off[1]))
                                         if x[k]]}
             for name, x, off in (("q", case.q0, chain.joint_qoff),
                                  ("v", case.v0, chain.joint_voff))}
    return case_with_links(case.path, links, f"{case.name}@{links}",
                           f"{case.path} (rebuilt at {links} links)", initial=first)


def case_with_links(path, links: int, name: str, source: str, *,
                    initial: dict | None = None) -> Case:
    """The case file at ``path`` read with its ``[chain] links`` set to ``links`` and its name
    to ``name`` (the file itself unchanged): the same rope, a ``link_length`` or ``link_mass``
    read as the whole rope's (times the file's count), so that the rope keeps its length and
    mass at the new count; ``source`` names it in messages. ``initial``: its ``[initial]``
    entries replaced by these (``q``, ``v``)."""
    doc = json.loads(json.dumps(read_toml(path)[0]))  # a deep copy
    chain, old = doc["chain"], int(doc["chain"]["links"])
    for each, whole in (("link_length", "total_length"), ("link_mass", "total_mass")):
        if each in chain:  # the same rope: its length and mass, not each link's, carried over
            chain[whole] = float(chain.pop(each)) * old
    chain["links"] = int(links)
    doc["case"]["name"] = name
    if initial:
        doc.setdefault("initial", {}).update(initial)
    return case_from_dict(doc, source=source, path=Path(path))
