"""What a run is: (scenario, engine and algorithm, integrator, tolerances or step, horizon,
sampling).

A :class:`RunSpec` is plain data (it pickles, it goes to a Dask worker, it is one row of a sweep's
cross product). Its ``case`` is any scenario (:mod:`redysim.io.scenarios`: a scenario file, a rope
case, a model file by itself). Its settings default to the scenario's ``[simulation]`` table: an
empty integrator and zero tolerances, step, horizon and sample interval mean "the scenario's",
and :meth:`RunSpec.resolved` fills them in (and checks every setting, naming the bad one). Its
:attr:`RunSpec.run_id` is a stable hash of its fields, of every byte that defines the scenario
(its file, its model's file) and of the code, so a resumed sweep can tell which runs are already
done, and never reuses a run computed from another version of the scenario or of the code.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

from redysim.algorithms.methods import METHODS as CORE_METHODS
from redysim.errors import SettingsError
from redysim.integrators.explicit import FIXED_STEP, canonical, check_settings
from redysim.io.scenarios import (
    MODEL_OPTIONS,
    Scenario,
    digest_of,
    source_files,
)

CORE = "redysim"  # the engine name of our own core
NATIVE = "native"  # integrator name: the engine's own time stepping ("native:NAME": one of them)
STEPPED = (*FIXED_STEP, NATIVE)  # integrators that take a step h, not tolerances (and an
# engine's fixed-step "native:NAME": :func:`stepped`)
PRECISIONS = ("float64", "float32")  # RunSpec.precision: the arithmetic of the core's qdd


def is_native(integrator) -> bool:
    """Whether ``integrator`` names a reference engine's own integrator: ``"native"`` (the
    engine's default) or ``"native:NAME"`` (one of the engine's ``integrators``)."""
    return isinstance(integrator, str) and (integrator == NATIVE or
                                            integrator.startswith(NATIVE + ":"))


def native_name(integrator: str) -> str | None:
    """The engine's integrator named by ``"native:NAME"`` (NAME), or None for ``"native"``."""
    return integrator.split(":", 1)[1] if ":" in integrator else None


__all__ = ["CORE", "CORE_METHODS", "NATIVE", "PRECISIONS", "STEPPED", "RunSpec", "case_digest",
           "is_native", "native_integrator", "native_name", "stepped"]


@dataclass(frozen=True)
class RunSpec:
    """One run.

    case:        a scenario (:mod:`redysim.io.scenarios`): a built-in scenario's or rope case's
                 name, or the path of a scenario, case or model file (.urdf, MJCF .xml, DH
                 robot or linkage .toml).
    engine:      ``"redysim"`` (the core) or a reference engine's name
                 (``redysim.references.ENGINES``).
    method:      for the core, ``"rge-a"`` (default), ``"ge-n"`` or ``"rge-n"``; ignored (``""``)
                 for an engine.
    integrator:  a name from ``redysim.integrators.explicit.INTEGRATORS`` (``"ode45"``,
                 ``"dop853"``, ``"rk4"``, ``"midpoint"`` alias ``"implicit"``, ``"midpoint-fixed"``,
                 ``"scipy-RK45"``, ...), ``"native"`` (the engine's default integrator) or
                 ``"native:NAME"`` (one of the engine's own, ``Engine.integrators``: a fixed-step
                 one needs ``h``, an adaptive one tolerances); ``""``: the case's (ode45 unless its
                 file says otherwise).
    rtol, atol:  tolerances of an adaptive integrator; 0: the case's (1e-4 and 1e-6 unless its
                 file says otherwise). A fixed-step integrator takes none.
    h:           the step of a fixed-step integrator (``rk4``, ``midpoint-fixed``, ``native``); 0:
                 the case's. An adaptive integrator takes none: it chooses its own steps.
    t_end:       horizon [s]; 0: the case's ``t_end``.
    sample:      sample interval [s]; 0: the case's (``sample_interval``, else t_end / 20).
    energy_bound: a run whose |delta_M| exceeds this [J/kg] is stopped and recorded as failed.
    max_cpu_s:   a run that has used this many seconds of CPU time (its process's, over the
                 integration; the JIT compile is timed apart) is stopped and recorded as failed (its
                 finished samples are kept); 0 means no limit. CPU time, not wall time: a limit that
                 decides a result must not depend on what else the machine is doing (a wall-clock
                 limit once failed a run on a busy machine when it had used a third of it in CPU).
                 It still depends on the machine's speed. A wall-clock limit is the user's patience
                 only: ``execute(max_wall_s=...)`` and ``redysim simulate --max-wall``, whose runs
                 are "stopped", never a result.
    perturb:     a rounding-level change of the initial state: every component y0_i of (q0, v0)
                 becomes y0_i + perturb * max(|y0_i|, 1), and E(0) is that state's energy. 0 (the
                 default) runs the case's own state. Ensembles of runs with perturb ~ 1e-13 show
                 how much a result depends on round-off (``sweeps/drift-ensemble.toml``).
    links:       the model's link count: the case's chain coarse-grained to this many links
                 (:func:`redysim.coarsen`: every k = n_links / links consecutive links lumped
                 into one), its initial state mapped by the coarsening's chord projection; a
                 count that does not divide the case's rebuilds a straight rope from its file
                 at that count (:func:`redysim.io.cases.rebuilt_case`: the same rope, as
                 lumping gives where both apply). 0 (the default): the case's own chain.
                 Refinement studies run one rope at several counts (``sweeps/refine-*.toml``).
    precision:   the arithmetic of the dynamics (qdd): ``"float64"`` (default) or
                 ``"float32"`` (the core only: every operation of the same kernel source rounded to
                 IEEE single, bias terms included, :func:`redysim.algorithms.precision.ieee_qdd`
                 with ``fused_phi``; numpy-emulated, so slow, and its CPU time says nothing of
                 float32's speed: ``benchmarks/float32_speed.py`` measures that). The integrator's
                 state and stage sums stay float64.
    options:     the model loader's options for a model file given by itself, as JSON
                 (:meth:`with_options`: floating, mimic, equality, lock); "" for none (a
                 scenario file sets its own).
    """

    case: str
    engine: str = CORE
    method: str = "rge-a"
    integrator: str = ""
    rtol: float = 0.0
    atol: float = 0.0
    h: float = 0.0
    t_end: float = 0.0
    sample: float = 0.0
    energy_bound: float = 1e3
    max_cpu_s: float = 0.0
    perturb: float = 0.0
    links: int = 0
    precision: str = "float64"
    options: str = ""

    def __post_init__(self):
        if self.engine != CORE and self.method in CORE_METHODS:
            object.__setattr__(self, "method", "")

    def with_options(self, **options) -> RunSpec:
        """This run with the model loader's options (floating, mimic, equality, lock; None
        values dropped) as canonical JSON."""
        given = {k: v for k, v in options.items() if v not in (None, False, {}, ())}
        unknown = set(given) - set(MODEL_OPTIONS)
        if unknown:
            raise SettingsError("run", "options", sorted(unknown),
                                f"unknown; known: {', '.join(MODEL_OPTIONS)}")
        return replace(self, options=json.dumps(given, sort_keys=True) if given else "")

    def model_options(self) -> dict:
        """The model loader's options (:attr:`options` read back)."""
        return json.loads(self.options) if self.options else {}

    def stepped(self, integrator: str) -> bool:
        """Whether ``integrator`` takes a step h for this run's engine (:func:`stepped`)."""
        return stepped(self.engine, integrator)

    def resolved(self, case, *, source: str = "run", names: dict[str, str] | None = None
                 ) -> RunSpec:
        """This run with every "the scenario's" setting taken from ``case`` (a loaded
        :class:`redysim.io.scenarios.Scenario`, or a rope :class:`redysim.Case`), and every
        setting checked: raises :class:`~redysim.errors.SettingsError` naming the field
        (renamed by ``names``, e.g. ``{"rtol": "--rtol"}``) and the value.

        A step given to an adaptive integrator, or tolerances to a fixed-step one, are refused
        rather than ignored."""
        names = names or {}
        scn = case if isinstance(case, Scenario) else Scenario.from_case(case)
        rope = scn.case
        if self.links:
            if rope is None:
                raise SettingsError(source, names.get("links", "links"), self.links,
                                    f"coarse-grains a rope case's chain; {scn.name} is a "
                                    f"{scn.kind} scenario")
            nl = rope.chain.n_links
            if isinstance(self.links, bool) or int(self.links) != self.links or self.links < 1:
                raise SettingsError(source, names.get("links", "links"), self.links,
                                    "must be a whole number of links >= 1")
            from redysim.io.cases import MAX_LINKS

            if self.links > MAX_LINKS:
                raise SettingsError(source, names.get("links", "links"), self.links,
                                    f"must be at most {MAX_LINKS:,} links (a case's limit)")
            if nl % int(self.links):
                from redysim.io.cases import rebuild_problem

                why = rebuild_problem(rope)
                if why:
                    raise SettingsError(source, names.get("links", "links"), self.links,
                                        f"does not divide the case's {nl} links (a coarse link "
                                        f"lumps the same number of fine ones), and the rope "
                                        f"cannot be rebuilt at that count: {why}")
        if self.precision not in PRECISIONS:
            raise SettingsError(source, names.get("precision", "precision"), self.precision,
                                f"choose one of {', '.join(PRECISIONS)}")
        if self.precision != "float64" and self.engine != CORE:
            raise SettingsError(source, names.get("precision", "precision"), self.precision,
                                f"reduced precision is the core's only (engine {self.engine!r} "
                                "computes in its own arithmetic)")
        integrator = self.integrator or scn.integrator
        integrator = canonical(integrator) if isinstance(integrator, str) else integrator
        native = is_native(integrator)
        if native:
            key = names.get("integrator", "integrator")
            if self.engine == CORE:
                raise SettingsError(source, key, integrator, "needs a reference engine: it is "
                                    "an engine's own integrator, and the core has none (choose "
                                    "an engine, or one of redysim's integrators)")
            if native_integrator(self.engine, integrator) is None:
                from redysim import references

                own = references.get(self.engine).integrators
                raise SettingsError(source, key, integrator, f"engine {self.engine!r} has no "
                                    f"such integrator; its own: "
                                    f"{', '.join('native:' + n for n in own) or 'none'}")
        stepped = self.stepped(integrator)
        t_end = self.t_end or scn.t_end
        sample = self.sample or scn.sample_for(t_end)
        if stepped:
            if self.rtol or self.atol:
                key = "rtol" if self.rtol else "atol"
                raise SettingsError(source, names.get(key, key), getattr(self, key),
                                    f"applies to adaptive integrators; {integrator!r} is "
                                    "fixed-step (give its step h)")
            h = self.h or (scn.h if integrator == scn.integrator else None)
            if not h:
                raise SettingsError(source, names.get("h", "h"), None,
                                    f"missing: integrator {integrator!r} is fixed-step and "
                                    "needs a step h > 0")
            rtol = atol = 0.0
        else:
            h = self.h or None  # refused below: an adaptive integrator takes no step
            if native and h:  # (check_settings knows ours only)
                raise SettingsError(source, names.get("h", "h"), h, f"is the step of a "
                                    f"fixed-step integrator; {integrator!r} is "
                                    "error-controlled (give its rtol and atol)")
            rtol, atol = self.rtol or scn.rtol, self.atol or scn.atol
        check_settings(source, names, method=None if native else integrator,
                       rtol=None if stepped else rtol,
                       atol=None if stepped else atol, h=h, t_end=t_end,
                       sample=min(sample, t_end), extra_methods=(NATIVE,))
        if self.t_end and self.t_end > scn.t_end and rope is not None:
            _check_horizon(rope, float(t_end), source, names.get("t_end", "t_end"))
        return replace(self, integrator=integrator, rtol=rtol, atol=atol, h=h or 0.0,
                       links=int(self.links),
                       t_end=float(t_end), sample=float(min(sample, t_end)))

    def unlike(self, row: dict) -> list[str]:
        """The fields of a stored run's ``row`` that cannot be this run's (a resolution of it,
        :meth:`resolved`, records every setting left to the case as the case's): a setting
        given here must be the row's (an integrator by its canonical name, the sample at most
        the horizon); the others the row fills in. [] when the row may be this run's."""
        wrong = []
        for f in fields(self):
            mine, theirs = getattr(self, f.name), row.get(f.name)
            if f.name in _RESOLVED and mine == f.default:
                continue  # left to the case: the row holds the case's
            if f.name == "integrator":
                mine = canonical(mine)
            elif f.name == "sample" and isinstance(theirs, int | float):
                mine = min(mine, float(row.get("t_end") or mine))
            same = (isinstance(theirs, int | float) and not isinstance(theirs, bool)
                    and float(theirs) == float(mine)) if isinstance(mine, int | float) \
                else type(theirs) is type(mine) and theirs == mine
            if not same:
                wrong.append(f.name)
        return wrong

    @property
    def run_id(self) -> str:
        """A stable 16-hex-digit id from every field, the case file's bytes
        (:func:`case_digest`) and the code that runs it
        (:func:`redysim.harness.provenance.code_digest`): same spec, case and code, same id, on
        any machine; a run finished from another version of the case or of the code is not
        reused."""
        from .provenance import code_digest
        blob = json.dumps({**asdict(self), "case_digest": case_digest(self.case, self.options),
                           "code": code_digest()}, sort_keys=True, default=repr)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]

    @property
    def label(self) -> str:
        """A short human label: ``RE-U125-L1 redysim/rge-a ode45 rtol=1e-06``; "case's" where a
        setting is left to the case."""
        algo = f"{self.engine}/{self.method}" if self.method else self.engine
        integrator = self.integrator or "case's integrator"
        if self.h:
            step = f" h={self.h:g}"
        elif self.rtol:
            step = f" rtol={self.rtol:g}"
        else:
            step = "" if integrator in STEPPED else " case's rtol"
        extra = f" perturb={self.perturb:g}" if self.perturb else ""
        if self.links:
            extra += f" links={self.links}"
        if self.precision != "float64":
            extra += f" {self.precision}"
        if self.options:
            extra += f" {self.options}"
        return f"{self.case} {algo} {integrator}{step}{extra}"

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))


# the settings a run may leave to its case (RunSpec.resolved fills them in)
_RESOLVED = frozenset({"integrator", "rtol", "atol", "h", "t_end", "sample", "links"})


def _check_horizon(case, t_end: float, source: str, name: str) -> None:
    """Refuse a horizon over which the case's fastest motion turns through more radians than a
    run can integrate (:data:`redysim.io.cases.MAX_RADIANS`), as its file's own t_end would be."""
    from redysim.io.cases import MAX_RADIANS, fastest_motion

    motion = fastest_motion(case.chain, case.tip_force, case.v0)
    if motion.omega * t_end > MAX_RADIANS:
        raise SettingsError(source, name, t_end,
                            f"the case's fastest motion, ~{motion.omega:.3g} rad/s, turns "
                            f"through ~{motion.omega * t_end:.3g} rad over it: more than the "
                            f"{MAX_RADIANS:.0e} a run can integrate; at most "
                            f"{MAX_RADIANS / motion.omega:.3g} s")


def stepped(engine: str, integrator: str) -> bool:
    """Whether ``integrator`` takes a step h (not tolerances) on ``engine``: ours of
    :data:`FIXED_STEP`, and an engine's fixed-step own ones (an unknown one counts as fixed:
    it is refused by name when the run is resolved)."""
    if is_native(integrator):
        info = native_integrator(engine, integrator)
        return info is None or not info.adaptive
    return integrator in FIXED_STEP


def native_integrator(engine: str, integrator: str):
    """The :class:`redysim.references.NativeIntegrator` that ``integrator`` ("native" or
    "native:NAME") names for ``engine``, or None when the engine has no such one (or is not
    an engine). Imports no engine package (the adapters' tables are class attributes)."""
    from redysim import references

    try:
        cls = references.get(engine)
    except KeyError:
        return None
    name = native_name(integrator) or cls.integrator
    return cls.integrators.get(name)


def case_digest(case: str, options: str = "") -> str:
    """SHA-256 over every file that defines the scenario (the scenario or case file, its model
    file) and the model options ("missing" when one cannot be read: the run then fails with the
    loader's message). Cached per file version (path, size, modification time)."""
    try:
        stats = tuple((str(Path(p).resolve()), st.st_size, st.st_mtime_ns, st.st_ino)
                      for p in source_files(case) for st in (os.stat(p),))
    except (OSError, ValueError):
        return "missing"
    return _digest(os.fspath(case), options, stats)


@functools.lru_cache(maxsize=1024)
def _digest(case: str, options: str, _stats: tuple) -> str:
    return digest_of(case, json.loads(options) if options else None)
