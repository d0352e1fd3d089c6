"""Robots by name: the model files of the ``example-robot-data`` package (installed with
``redysim[test]``), named wherever a model file is taken.

``example-robot-data:<name>`` is such a file, by either of

- its **short name**: the file's stem (``ur5_robot``, ``talos_reduced``, ``panda``), and the
  stem without a trailing ``_robot`` where no other file has that stem (``ur5``, ``ur10``; the
  package's ``ur3.urdf`` keeps ``ur3``). A stem two files share (``anymal``) names neither:
  the message lists both by their paths;
- the **end of its path** in the package (``ur_description/urdf/ur5_robot.urdf``, or just
  ``ur5_robot.urdf``), the form scenario files have always used; an end that two files share is
  refused the same way.

:func:`resolve` is what every loader calls first (``load_model``, ``load_urdf``,
``load_mjcf``, the scenario loader and so ``redysim info``, ``simulate``, ``compare``,
``advise`` and a sweep's ``case`` fields): a prefixed name becomes the file's path; a bare file
name that does not exist where it is given but is a file of the package is refused with the
prefixed form to use (never taken from the package silently: a file of that name in the
working directory would otherwise change what a command means). :func:`robots` is the table
``redysim robots`` prints.
"""

from __future__ import annotations

import difflib
import functools
import os
from importlib import metadata
from pathlib import Path

PREFIX = "example-robot-data:"
PACKAGE = "example-robot-data"
# the suffixes of the package's model files (it ships URDFs; SRDF, meshes and the rest are not
# models)
MODEL_SUFFIXES = (".urdf", ".xml")
ROBOTS_DIR = "/robots/"  # the package's files of robots are under share/example-robot-data/robots


@functools.lru_cache(maxsize=1)
def _package_files() -> tuple[tuple[str, Path], ...] | None:
    """(path inside the package's robots folder, absolute path) of every model file of
    example-robot-data, sorted; None when the package is not installed. Cached: reading the
    package's list of files is slow next to a run's id, which asks for it."""
    try:
        dist = metadata.distribution(PACKAGE)
    except metadata.PackageNotFoundError:
        return None
    out = []
    for f in dist.files or ():
        text = str(f).replace("\\", "/")
        if ROBOTS_DIR in text and text.lower().endswith(MODEL_SUFFIXES):
            rel = text.split(ROBOTS_DIR, 1)[1]
            out.append((rel, Path(str(dist.locate_file(f)))))
    return tuple(sorted(out))


@functools.lru_cache(maxsize=1)
def _short_names() -> dict[str, tuple[str, ...]]:
    """Short name -> the package paths it could mean (one: a name; more: ambiguous)."""
    files = _package_files() or ()
    stems: dict[str, list[str]] = {}
    for rel, _ in files:
        stems.setdefault(Path(rel).stem, []).append(rel)
    names = {k: tuple(v) for k, v in stems.items()}
    for stem, rels in stems.items():
        short = stem.removesuffix("_robot")
        if short != stem and short not in stems:
            names[short] = tuple(rels)
    return names


def robots() -> list[tuple[str, str]]:
    """(short name, path in the package) of every model file of example-robot-data, sorted by
    name; a file whose stem is shared has no short name (its name is ``""``: give its path).
    Empty when the package is not installed."""
    by_file: dict[str, str] = {}
    for name, rels in _short_names().items():  # the shortest unambiguous name of each file
        if len(rels) == 1 and len(name) < len(by_file.get(rels[0], name + "_")):
            by_file[rels[0]] = name
    files = _package_files() or ()
    return sorted(((by_file.get(rel, ""), rel) for rel, _ in files),
                  key=lambda r: (r[0] or "~", r[1]))


def robot_file(name: str) -> Path:
    """The file of example-robot-data that ``name`` (after the prefix) names, by short name or
    by the end of its path (module docstring). Raises FileNotFoundError saying why not: the
    package missing, no such robot (with the nearest names), or a name two files share (with
    both paths)."""
    given = f"{PREFIX}{name}"
    files = _package_files()
    if files is None:
        raise FileNotFoundError(f"model file {given!r}: the {PACKAGE} package is not installed "
                                f"(pip install {PACKAGE}, or redysim[test])")
    key = name.strip().replace("\\", "/").lstrip("/")
    if not key:
        raise FileNotFoundError(f"model file {given!r}: no robot named; 'redysim robots' "
                                "lists them")
    if "/" not in key and Path(key).suffix.lower() not in MODEL_SUFFIXES:
        rels = _short_names().get(key, ())
    else:
        rels = tuple(rel for rel, _ in files if rel == key or rel.endswith("/" + key))
    if len(rels) > 1:
        raise FileNotFoundError(f"model file {given!r} is ambiguous: {PACKAGE} has "
                                + ", ".join(f"{PREFIX}{r}" for r in rels) + "; give one")
    if not rels:
        near = difflib.get_close_matches(key, list(_short_names()) +
                                         [rel for rel, _ in files], n=3)
        hint = f"; nearest: {', '.join(PREFIX + n for n in near)}" if near else ""
        raise FileNotFoundError(f"model file {given!r}: {PACKAGE} has no such robot"
                                f"{hint} ('redysim robots' lists them)")
    return dict(files)[rels[0]]


def package_hint(text: str) -> str:
    """For a bare file name that example-robot-data has (``ur5_robot.urdf``): the prefixed
    names to give instead, as a clause to append to a "does not exist" message; else ``""``."""
    if "/" in text or "\\" in text or text.startswith(PREFIX):
        return ""
    files = _package_files() or ()
    rels = [rel for rel, _ in files if rel.endswith("/" + text)]
    if not rels:
        return ""
    names = {rel: name for name, rel in robots() if name}
    forms = [f"{PREFIX}{names[r]}" if r in names else f"{PREFIX}{r}" for r in rels]
    return f"; {PACKAGE} has it: give {' or '.join(forms)}"


def resolve(path: str | os.PathLike) -> str | os.PathLike:
    """``path`` as a loader takes it: ``example-robot-data:<name>`` becomes the file's path
    (:func:`robot_file`); anything else is returned as it is, except a bare file name that is
    no file here but one of example-robot-data's, which raises FileNotFoundError naming the
    prefixed form."""
    text = os.fspath(path)
    if isinstance(text, str) and text.startswith(PREFIX):
        return robot_file(text[len(PREFIX):])
    if isinstance(text, str) and Path(text).suffix.lower() in MODEL_SUFFIXES \
            and not os.path.exists(text):
        hint = package_hint(text)
        if hint:
            raise FileNotFoundError(f"model file {text!r} does not exist{hint}")
    return path
