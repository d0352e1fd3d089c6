"""File kinds: what a file given to redysim is, and how its model is read. One class per kind,
one ordered registry (:data:`KINDS`); every place that needs to know a file's kind asks it.

A kind (:class:`FileKind`) says, as data, how it is named in messages (``noun``) and help
(``files``), how it is detected (its ``suffixes`` and, for a ``.toml``, the ``table`` that marks
it), which of a model's options it takes (``options``: floating, mimic, equality, lock) or why
it takes none (``fixed``), and whether its file is a rope case (``rope``: ``--links``,
``--precision``, the rope's own study); and as methods, how it reads a model
(:meth:`FileKind.model`, :func:`load_model`'s contract) and what a scenario takes from its file
(:meth:`FileKind.load`: the model with its options, and the file's own initial configuration,
driver or rope case, where it has one).

Detection is in :data:`KINDS`' order, the first kind that detects a file wins: a ``.toml``
with a ``[scenario]`` table before a protein, DH robot or linkage ``.toml`` (a DH robot's
before a linkage's, as they have always been told apart), and any other ``.toml`` last, a rope
case. A name without a kind's suffix is a rope case's (:func:`kind_of`); a built-in scenario's
name is resolved by the scenario loader first (:func:`redysim.io.scenarios.scenario_path`).

A new kind is one class here, listed in :data:`KINDS` (or, from outside, :func:`register`):
the scenario loader, ``load_model``, ``redysim simulate``, ``info``, ``advise`` and ``compare``
and their help take it from the registry. ``tests/test_kinds.py`` adds a kind of its own and
shows each of them taking it.
"""

from __future__ import annotations

import functools
import os
import stat
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from redysim.errors import CaseError
from redysim.io.cases import Case, has_table, load_case
from redysim.io.importers import EQUALITY, MIMIC, ModelFileError, _check_choice, _check_flags
from redysim.io.robots import resolve
from redysim.model.tree import Model

# the suffix of redysim's own files (cases, scenarios, DH robots, linkages, proteins), which their
# tables tell apart
TOML = ".toml"
# the model options that load_model takes; the other, "lock", is applied to the loaded model
LOADER_ARGS = ("floating", "mimic", "equality")


@dataclass(frozen=True)
class Loaded:
    """What a scenario takes from a model file (:meth:`FileKind.load`): its ``model`` (options
    applied), the file's own initial configuration ``q0`` (None: ``model.initial()``; a
    linkage's, assembled from its driver), the index of its driving coordinate ``driver`` (None
    without one), and ``case``: the rope case, for a rope case file (its settings, tip force
    and coarsenings), else None."""

    model: Model
    q0: np.ndarray | None = None
    driver: int | None = None
    case: Case | None = None


class FileKind:
    """One kind of file (module docstring). A subclass sets the data below and implements
    :meth:`model`; it overrides :meth:`load` where its file holds more than a tree, and
    :meth:`detects` where a suffix and a table do not tell it."""

    name: str = ""  # "urdf": Scenario.kind, a run's record
    noun: str = ""  # "a URDF": in messages ("a URDF has no use for it")
    files: str = ""  # how its files are told, for help: ".urdf (read by redysim)"
    suffixes: tuple[str, ...] = ()  # lower case, with the dot
    table: str | None = None  # a .toml kind: the table that marks it (a "[table]" line)
    options: tuple[str, ...] = ()  # the model options it takes (floating, mimic, equality, lock)
    fixed: str = ""  # why it takes none: its file sets its model ("a linkage file's driver ...")
    rope: bool = False  # a rope case: --links, --precision, the rope's own study

    def detects(self, path: str) -> bool:
        """Whether ``path`` is of this kind: its suffix and, for a kind with a ``table``, a
        ``[table]`` line in the file (read as text; False for a file that cannot be read)."""
        return Path(path).suffix.lower() in self.suffixes and (
            self.table is None or has_table(path, self.table))

    def model(self, path: Path, *, floating: bool = False, mimic: str = "couple",
              equality: str = "close", strict: bool = False) -> Model:
        """The model in the file (:func:`load_model`'s contract, its arguments checked):
        ``floating``, ``mimic``, ``equality`` and ``strict`` as the kind's reader takes them, or
        a ModelFileError naming why it cannot."""
        raise NotImplementedError

    def load(self, path: str | os.PathLike, options: dict[str, Any], *, source: str) -> Loaded:
        """What a scenario takes from the file: the model with ``options`` (floating, mimic,
        equality, lock) applied, each checked against the kind's (:meth:`check_options`);
        ``source`` names the scenario in a refusal."""
        self.check_options(source, options)
        given = {k: v for k, v in options.items() if _given(v)}
        p = Path(path)
        model = self.model(p, **_loader_args(str(p), **{k: v for k, v in given.items()
                                                         if k in LOADER_ARGS}))
        lock = given.get("lock")
        if lock:
            if not isinstance(lock, dict):
                raise CaseError(source, "model.lock", lock, "must be a table {joint = value}")
            try:
                model = model.locked(lock)
            except (KeyError, ValueError) as exc:
                raise CaseError(source, "model.lock", lock, str(exc).strip("'\"")) from None
        return Loaded(model)

    def check_options(self, source: str, options: dict[str, Any]) -> None:
        """Refuse, by name, an option the kind does not take (a value of None, False or {} is
        none given)."""
        for key, value in options.items():
            if not _given(value) or key in self.options:
                continue
            if not self.options:
                raise CaseError(source, f"model.{key}", value,
                                f"{self.fixed}; it takes no model options")
            raise CaseError(source, f"model.{key}", value,
                            f"{self.noun} takes {either(self.options, 'and')}, not {key}")

    def __repr__(self) -> str:
        return f"<file kind {self.name!r}>"


def _given(value) -> bool:
    return value not in (None, False, {})


def _loader_args(src: str, *, floating=False, mimic="couple", equality="close",
                 strict=False) -> dict[str, Any]:
    """load_model's arguments, checked as the readers check them (ModelFileError naming the one
    that is wrong), for every kind alike."""
    _check_flags(src, floating=floating, strict=strict)
    _check_choice(src, "mimic", mimic, MIMIC)
    _check_choice(src, "equality", equality, EQUALITY)
    return {"floating": floating, "mimic": mimic, "equality": equality, "strict": strict}


def either(items: Iterable[str], last: str = "or") -> str:
    """"a, b or c" (``last``: "or", "and")."""
    items = list(items)
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} {last} {items[-1]}"


# --------------------------------------------------------------------------- the kinds
class ScenarioKind(FileKind):
    """A scenario file: a model file, a state, a horizon and what to observe; read by
    :func:`redysim.io.scenarios.load_scenario`, not by a model loader."""

    name, noun, table = "scenario", "a scenario file", "scenario"
    files = "a .toml with [scenario], or a name in cases/scenarios/"
    suffixes = (TOML,)
    fixed = "a scenario file sets its model's options in its [model] table"

    def model(self, path, **_) -> Model:
        raise ModelFileError(str(path), "[scenario]", None, "a scenario file, not a model "
                             "file: load it with redysim.io.scenarios.load_scenario(path), whose "
                             ".model is its model")


class ProteinKind(FileKind):
    """A protein backbone (:mod:`redysim.io.proteins`): floats if asked."""

    name, noun, table = "protein", "a protein file", "protein"
    files = "a .toml with [protein] (cases/proteins/)"
    suffixes = (TOML,)
    options = ("floating", "lock")

    def model(self, path, *, floating=False, **_) -> Model:
        from redysim.io.proteins import load_protein

        return load_protein(path, floating=True if floating else None).model


class DhKind(FileKind):
    """A robot's DH table (:mod:`redysim.io.dh`), its base fixed in the world."""

    name, noun = "dh", "a DH robot file"
    files = "a .toml with [robot] or [[link]] (cases/robots/)"
    suffixes = (TOML,)
    options = ("lock",)

    def detects(self, path: str) -> bool:
        from redysim.io.dh import is_robot_file

        return Path(path).suffix.lower() in self.suffixes and is_robot_file(path)

    def model(self, path, *, floating=False, **_) -> Model:
        from redysim.io.dh import load_robot

        if floating:
            raise ModelFileError(str(path), "floating", True, "a DH robot's base is its table's "
                                 "frame 0, fixed in the world, and the file gives no base body "
                                 "(mass, inertia) to float: load without floating=True")
        return load_robot(path).model


class LinkageKind(FileKind):
    """A closed-loop linkage (:mod:`redysim.io.linkage_files`): its tree, its cut joints, its
    assembled configuration and its driver; its named points are frames a scenario can
    observe ("coupler.P")."""

    name, noun = "linkage", "a linkage file"
    files = "a .toml with [linkage] (cases/loops/)"
    suffixes = (TOML,)
    fixed = "a linkage file's driver and cut joints set its motion"

    def detects(self, path: str) -> bool:
        from redysim.io.linkage_files import is_linkage_file

        return Path(path).suffix.lower() in self.suffixes and is_linkage_file(path)

    def model(self, path, **_) -> Model:
        raise ModelFileError(str(path), "[linkage]", None, "a closed-loop linkage: a tree alone "
                             "would drop its cut joints; load it with "
                             "redysim.load_linkage(path) -> (model, loops, q0)")

    def load(self, path, options, *, source) -> Loaded:
        from redysim.io.linkage_files import load_linkage

        self.check_options(source, options)
        linkage = load_linkage(path)
        points = {name: (int(b), (float(pt[0]), float(pt[1]), float(pt[2])))
                  for name, (b, pt) in linkage.points.items() if b >= 0}
        model = linkage.model
        if points:
            model = replace(model, frames={**model.frames, **points})
        return Loaded(model, q0=linkage.q0, driver=linkage.driver)


class UrdfKind(FileKind):
    """A URDF, read by redysim (:func:`redysim.io.importers.load_urdf`)."""

    name, noun, files = "urdf", "a URDF", ".urdf (read by redysim)"
    suffixes = (".urdf",)
    options = ("floating", "mimic", "lock")

    def model(self, path, *, floating=False, mimic="couple", strict=False, **_) -> Model:
        from redysim.io.importers import load_urdf

        return load_urdf(path, floating=floating, mimic=mimic, strict=strict)


class MjcfKind(FileKind):
    """An MJCF file, compiled by MuJoCo (:func:`redysim.io.importers.load_mjcf`)."""

    name, noun = "mjcf", "an MJCF file"
    files = ".xml (compiled by MuJoCo: the 'models' extra)"
    suffixes = (".xml",)
    options = ("floating", "equality", "lock")

    def model(self, path, *, floating=False, equality="close", strict=False, **_) -> Model:
        from redysim.io.importers import load_mjcf

        return load_mjcf(path, floating=floating, equality=equality, strict=strict)


class CaseKind(FileKind):
    """A rope case (:mod:`redysim.io.cases`): its chain, state, settings and tip force. Any
    ``.toml`` no other kind detects, and a name (:func:`kind_of`)."""

    name, noun = "case", "a rope case"
    files = "any other .toml, or a name in cases/ (redysim cases)"
    suffixes = (TOML,)
    fixed = "a rope case has no named joints and no base body to float"
    rope = True

    def model(self, path, *, floating=False, **_) -> Model:
        if floating:
            raise ModelFileError(str(path), "floating", True, "a rope case's first joint is fixed "
                                 "to the world and the file gives no base body to float: load "
                                 "without floating=True")
        return load_case(path).chain

    def load(self, path, options, *, source) -> Loaded:
        self.check_options(source, options)
        case = load_case(path)  # a path, or a built-in case's name
        return Loaded(case.chain, case=case)


CASE = CaseKind()
# detection order: the first kind that detects a file is its kind (module docstring)
KINDS: list[FileKind] = [UrdfKind(), MjcfKind(), ScenarioKind(), ProteinKind(), DhKind(),
                         LinkageKind(), CASE]


# --------------------------------------------------------------------------- the registry
def register(kind: FileKind, *, before: str = CASE.name) -> None:
    """Add ``kind`` to :data:`KINDS`, detected just before the kind named ``before`` (default:
    before the rope case, which takes any .toml)."""
    names = [k.name for k in KINDS]
    if kind.name in names:
        raise ValueError(f"a file kind named {kind.name!r} is registered already")
    if before not in names:
        raise ValueError(f"no file kind named {before!r}; known: {', '.join(names)}")
    KINDS.insert(names.index(before), kind)
    _detect_file.cache_clear()


def unregister(name: str) -> None:
    """Remove the kind named ``name`` from :data:`KINDS`."""
    KINDS[:] = [k for k in KINDS if k.name != name]
    _detect_file.cache_clear()


def detect(path: str | os.PathLike) -> FileKind | None:
    """The kind of the file ``path``, None when no kind detects it (a name, or a suffix no kind
    has). A regular file's kind is kept per version of it (its size, modification time and
    inode): a sweep's worker asks for the kinds of its run's files several times a run, and a
    .toml's kind reads it up to four times."""
    text = os.fspath(path)
    try:
        st = os.stat(text)
    except (OSError, ValueError):
        st = None
    if st is not None and stat.S_ISREG(st.st_mode):
        return _detect_file(text, st.st_size, st.st_mtime_ns, st.st_ino)
    return next((k for k in KINDS if k.detects(text)), None)


@functools.lru_cache(maxsize=1024)
def _detect_file(path: str, _size: int, _mtime_ns: int, _ino: int) -> FileKind | None:
    return next((k for k in KINDS if k.detects(path)), None)


def kind_of(path: str | os.PathLike) -> FileKind:
    """:func:`detect`'s kind, and for anything no kind detects (a name, a file of another
    suffix) the rope case's: the case loader then says what is wrong with it."""
    return detect(path) or CASE


def by_suffix(path: str | os.PathLike) -> bool:
    """Whether the suffix of ``path`` alone says its kind (``.urdf``, ``.xml``): a file, never
    the name of a built-in case or scenario. (A ``.toml`` is every redysim file's.)"""
    suffix = Path(path).suffix.lower()
    return suffix != TOML and any(suffix in k.suffixes for k in KINDS)


def load_model(path: str | os.PathLike, *, floating: bool = False, mimic: str = "couple",
               equality: str = "close", strict: bool = False, armature=None) -> Model:
    """The model in ``path``, read as its kind reads it (:data:`KINDS`): ``.urdf``
    (:func:`~redysim.io.importers.load_urdf`: ``floating``, ``mimic``, ``strict``), MJCF ``.xml``
    (:func:`~redysim.io.importers.load_mjcf`: ``floating``, ``equality``, ``strict``), a
    protein ``.toml`` (:mod:`redysim.io.proteins`: ``floating=True`` frees its first residue),
    a robot ``.toml`` (a DH table, :mod:`redysim.io.dh`) or a case ``.toml`` (its chain), whose
    base is the world: ``floating=True`` is refused for them; a linkage or scenario file is
    refused, naming its own loader. ``armature``: the joints' own inertia, replacing the file's
    (a URDF has no tag for it; :meth:`Model.with_armature`'s values: a number, n_v numbers, or
    joint name -> value). Raises FileNotFoundError, ModelFileError or CaseError."""
    if isinstance(path, bool) or not isinstance(path, str | os.PathLike):
        raise CaseError("load_model", "path", path, "must be the path of a model file (a str "
                        "or a pathlib.Path), or 'example-robot-data:<name>'")
    p = Path(resolve(path))  # example-robot-data:<name>: redysim.io.robots
    src = str(p)
    args = _loader_args(src, floating=floating, mimic=mimic, equality=equality, strict=strict)
    if not p.is_file():
        raise FileNotFoundError(f"model file {src!r} does not exist")
    kind = detect(p)
    if kind is None:
        known = list(dict.fromkeys(s for k in KINDS for s in k.suffixes))
        raise ModelFileError(src, "<file>", p.suffix.lower(), f"a model file is {either(known)}")
    model = kind.model(p, **args)
    return model if armature is None else model.with_armature(armature, source=src)
