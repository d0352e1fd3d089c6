"""The package's layers depend one way: core <- references <- harness <- reports.

Inside the core, one way too: the shared ``redysim/errors.py`` and ``redysim/_jit.py`` <- model
(``redysim/model/``) <- algorithms (``redysim/algorithms/``, with its kernels) <- integrators
(``redysim/integrators/``) <- the driver (``redysim/simulation.py``) <- files
(``redysim/io/``); no core module imports the package ``redysim`` itself, whose lazy public names
would hide an upward import. The core imports none of the others; the engine adapters
(``references/``) import only the core; the harness (``harness/``: runs, sweeps, the CLI) imports
the core and the adapters, never the reports; and no two modules import each other, directly or
round a longer cycle, not even from inside a function. The kernels
(``redysim.algorithms._kernels``) are the core's private code: no module outside the core imports
them; it takes their passes from the core's door, :mod:`redysim.algorithms.precision`. Read from the
source with :mod:`ast`, so a lazy import inside a function counts as much as one at the top.

The folders ``harness/``, ``references/`` and ``reports/`` are importable under one name only,
``redysim.harness``, ``redysim.references`` and ``redysim.reports`` (the names they install
under), and every dotted module path a docstring or comment gives is an importable one.
"""

from __future__ import annotations

import ast
import io
import os
import re
import subprocess
import sys
import tokenize
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
# installed name -> folder in the repository (pyproject.toml's package-dir)
LAYERS = {"redysim": REPO / "redysim", "redysim.references": REPO / "references",
          "redysim.harness": REPO / "harness", "redysim.reports": REPO / "reports"}
ORDER = ["redysim", "redysim.model", "redysim.algorithms", "redysim.integrators",
         "redysim.simulation", "redysim.io", "redysim.references", "redysim.harness",
         "redysim.reports"]
CORE = ORDER[:6]


def modules() -> dict[str, Path]:
    out = {}
    for package, folder in LAYERS.items():
        for path in folder.rglob("*.py"):
            parts = path.relative_to(folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join((package, *parts))] = path
    return out


MODULES = modules()


def layer(name: str) -> str:
    return max((p for p in ORDER if name == p or name.startswith(p + ".")), key=len)


def imports(name: str, path: Path) -> set[str]:
    """The project modules ``name`` imports, anywhere in its source."""
    tree = ast.parse(path.read_text(), str(path))
    is_package = path.name == "__init__.py"
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base if is_package else base[:-1]
                base = base[:len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [mod] + [f"{mod}.{a.name}" for a in node.names]
        else:
            continue
        for t in targets:
            # the longest project module the target names (a name imported from a module is
            # the module itself)
            while t and t not in MODULES:
                t = t.rpartition(".")[0]
            if t and t != name:
                out.add(t)
    return out


GRAPH = {name: imports(name, path) for name, path in MODULES.items()}


@pytest.mark.parametrize("name", sorted(MODULES))
def test_imports_go_down_the_layers_only(name):
    mine = ORDER.index(layer(name))
    upward = sorted(t for t in GRAPH[name] if ORDER.index(layer(t)) > mine)
    assert not upward, f"{name} ({MODULES[name].relative_to(REPO)}) imports {upward}"


@pytest.mark.parametrize("name", sorted(m for m in MODULES if layer(m) in CORE and m != "redysim"))
def test_the_core_imports_its_modules_not_its_public_names(name):
    """``from redysim import simulate`` inside the model layer would import the driver through
    the package's lazy names, an upward import the layer check could not see."""
    assert "redysim" not in GRAPH[name], f"{name} imports the package redysim itself"


def test_no_import_cycles():
    """A cycle through ``__init__`` (a package importing its own submodule) is not a cycle of
    modules; any other is."""
    def edges(name):
        return {t for t in GRAPH[name] if not (name.startswith(t + ".") and
                                                MODULES[t].name == "__init__.py")}

    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(name):
        state[name] = 1
        stack.append(name)
        for t in sorted(edges(name)):
            if state.get(t) == 1:
                cycle = stack[stack.index(t):] + [t]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if t not in state:
                visit(t)
        stack.pop()
        state[name] = 2

    for name in sorted(MODULES):
        if name not in state:
            visit(name)


KERNELS = "redysim.algorithms._kernels"


def kernel_imports(name: str) -> list[str]:
    """The modules of the private kernels (``redysim.algorithms._kernels`` and anything under
    it) that ``name`` imports."""
    return sorted(t for t in GRAPH[name] if t == KERNELS or t.startswith(KERNELS + "."))


@pytest.mark.parametrize("name", sorted(m for m in MODULES if layer(m) not in CORE))
def test_no_module_outside_the_core_imports_the_kernels(name):
    """The kernels are the core's private code: the engine adapters, the harness and the reports
    reach them through the core's one door, ``redysim.algorithms.precision`` (its passes by name:
    compiled, as Python source, rebound to another arithmetic; the sources' digest), so that the
    kernels' files and names can change without them. Lazy imports inside functions count.

    ``benchmarks/`` is exempt (not walked): ``benchmarks/ab_kernels.py`` times the kernels' passes
    of two revisions on purpose; so are the tests."""
    assert not kernel_imports(name), (
        f"{name} ({MODULES[name].relative_to(REPO)}) imports {kernel_imports(name)}")


def test_the_walk_sees_the_project():
    """The checks above read something: every layer has modules, and a known edge is found."""
    assert all(any(layer(m) == p for m in MODULES) for p in ORDER)
    assert "redysim.harness.spec" in GRAPH["redysim.harness.run"]
    assert "redysim.model.tree" in GRAPH["redysim.algorithms.dynamics"]
    assert layer("redysim.algorithms._kernels.rge_a") == "redysim.algorithms"
    assert kernel_imports("redysim.algorithms.precision"), "the door's own imports are seen"


# --------------------------------------------------------------------------- one name per folder
def python_in_checkout(code: str) -> subprocess.CompletedProcess:
    """``python -c CODE`` started in the checkout's root, where Python puts the root (and so
    the folders harness/, references/, reports/) first on sys.path."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONSAFEPATH"}
    return subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True,
                          text=True)


@pytest.mark.parametrize("folder", ["harness", "references", "reports"])
def test_a_folder_imports_only_under_its_installed_name(folder):
    """``import harness`` from the checkout's root would load every module of harness/ a second
    time, as ``harness.*`` beside ``redysim.harness.*``: two RunSpec classes, two engine
    registries, isinstance failing between them. It is refused, naming the one name."""
    out = python_in_checkout(f"import {folder}")
    assert out.returncode == 1 and "ImportError" in out.stderr, out.stderr
    assert f"redysim.{folder}" in out.stderr, out.stderr
    ok = python_in_checkout(f"import redysim.{folder}")
    assert ok.returncode == 0, ok.stderr


# --------------------------------------------------------------------------- importable paths
# a dotted path on a folder's bare name: harness.run, not redysim.harness.run or harness/run.py
BARE_PATH = re.compile(r"(?<![\w./-])(harness|references|reports)\.[A-Za-z_]\w*")
# a Sphinx role on a folder's bare name: :mod:`references`
BARE_ROLE = re.compile(r":\w+:`~?(harness|references|reports)`")
# a name an example in the docstring binds itself (``from redysim import references``)
BOUND = re.compile(r"from redysim import ([\w, ]+)")
SCANNED = ("redysim", "harness", "references", "reports", "cases", "paper", "sweeps")


def docstrings_and_comments(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every docstring (module, class, function) and comment of a file."""
    src = path.read_text()
    out = []
    for node in ast.walk(ast.parse(src, str(path))):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            doc = ast.get_docstring(node, clean=False)
            if doc is not None:
                out.append((node.body[0].lineno, doc))
    tokens = tokenize.generate_tokens(io.StringIO(src).readline)
    out += [(tok.start[0], tok.string) for tok in tokens if tok.type == tokenize.COMMENT]
    return out


def bare_paths(text: str) -> list[str]:
    """The dotted paths in ``text`` that start with a folder's bare name (not importable once
    installed), except an attribute of a name the text's own example binds
    (``references.get(...)`` after ``from redysim import references``; ``references.base``
    names a module, and counts)."""
    bound = {n.strip() for m in BOUND.finditer(text) for n in m.group(1).split(",")}

    def module(folder: str, name: str) -> bool:
        return (REPO / folder / f"{name}.py").is_file() or (REPO / folder / name).is_dir()

    return [m.group(0) for m in BARE_PATH.finditer(text)
            if m.group(1) not in bound or module(m.group(1), m.group(0).split(".")[1])] + [
        m.group(0) for m in BARE_ROLE.finditer(text)]


def test_bare_paths_are_told_from_importable_ones():
    """The scan below finds what it looks for, and only that."""
    assert bare_paths("see :mod:`harness.run` and reports.results; python -m references.x") == [
        "harness.run", "reports.results", "references.x"]
    assert bare_paths("the adapters of :mod:`references`") == [":mod:`references`"]
    assert bare_paths("redysim.harness.run, harness/run.py, the references. Then, "
                      "results/reports.html, :mod:`redysim.references`, the ``harness`` "
                      "extra") == []
    assert bare_paths("from redysim import references\nreferences.get('mujoco'), "
                      "references.base.Engine") == ["references.base"]


def test_docstrings_and_comments_give_importable_module_paths():
    """Installed, there is no module ``harness.run``: only ``redysim.harness.run`` (and
    ``redysim.references.*``, ``redysim.reports.*``). A path to a file of the repository
    (``harness/run.py``) is a path, not a module, and is fine."""
    bad = [f"{path.relative_to(REPO)}:{line}: {name}"
           for folder in SCANNED for path in sorted((REPO / folder).rglob("*.py"))
           for line, text in docstrings_and_comments(path) for name in bare_paths(text)]
    assert not bad, f"{len(bad)} bare module paths:\n" + "\n".join(bad)


# --------------------------------------------------------------------------- paths that exist
DOTTED = re.compile(r"(?<![\w./-])redysim(?:\.[A-Za-z_]\w*)+")
FILE_PATH = re.compile(r"(?<![\w./-])redysim/[\w/]+\.(?:py|md|toml)\b")


# the data folders' installed names (pyproject.toml's package-dir): packages without modules
DATA = {"case_files", "paper", "sweep_files"}
# files that name the old layout on purpose: the A/B benchmark reads revisions before the layers;
# this file's own examples
OLD_LAYOUT_ON_PURPOSE = {"benchmarks/ab_kernels.py", "tests/test_layout.py"}


def top_level_names(path: Path) -> set[str]:
    """The names a module defines or imports at its top level (and, for the package
    ``redysim``, its lazy public names)."""
    tree = ast.parse(path.read_text(), str(path))
    names = set()
    body = list(tree.body)
    while body:
        node = body.pop()
        if isinstance(node, ast.If | ast.Try):  # if TYPE_CHECKING: ... else: ...
            body += node.body + node.orelse + getattr(node, "finalbody", [])
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names |= {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}
        elif isinstance(node, ast.Import | ast.ImportFrom):
            names |= {(a.asname or a.name).split(".")[0] for a in node.names}
    if path == REPO / "redysim" / "__init__.py":
        import redysim
        names |= set(redysim.__all__)
    return names


def stale_path(dotted: str) -> str | None:
    """Why ``dotted`` (redysim.a.b...) names nothing, or None: its longest module prefix must
    exist and the next part be a submodule or a top-level name of that module."""
    parts = dotted.split(".")
    if parts[1] in DATA or parts[-1].startswith("__"):
        return None
    k = max(i for i in range(1, len(parts) + 1) if ".".join(parts[:i]) in MODULES)
    if k == len(parts):
        return None
    module = ".".join(parts[:k])
    if parts[k] not in top_level_names(MODULES[module]):
        return f"{module} has no {parts[k]!r}"
    return None


def test_a_stale_dotted_path_is_found():
    assert stale_path("redysim.algorithms.dynamics.forward_dynamics") is None
    assert stale_path("redysim.forward_dynamics") is None
    assert stale_path("redysim.model.tree.Chain.uniform") is None
    assert stale_path("redysim.dynamics.forward_dynamics") == "redysim has no 'dynamics'"
    assert stale_path("redysim.model.Chain") == "redysim.model has no 'Chain'"


def text_files() -> list[Path]:
    py = [p for folder in SCANNED for p in sorted((REPO / folder).rglob("*.py"))]
    py += sorted((REPO / "tests").rglob("*.py")) + sorted((REPO / "benchmarks").rglob("*.py"))
    md = sorted(REPO.glob("*.md")) + sorted((REPO / "docs").rglob("*.md")) + [
        p for folder in SCANNED for p in sorted((REPO / folder).rglob("*.md"))]
    return py + md + [p for folder in SCANNED for p in sorted((REPO / folder).rglob("*.toml"))]


def test_every_redysim_path_in_code_and_docs_names_something_that_exists():
    """After the core moved into layers, a docstring, comment, README line or case file that
    still says ``redysim.dynamics`` or ``redysim/model.py`` points at nothing."""
    bad = []
    for path in text_files():
        if str(path.relative_to(REPO)) in OLD_LAYOUT_ON_PURPOSE:
            continue
        text = path.read_text()
        for m in DOTTED.finditer(text):
            why = stale_path(m.group(0).rstrip("."))
            if why:
                bad.append(f"{path.relative_to(REPO)}: {m.group(0)}: {why}")
        for m in FILE_PATH.finditer(text):
            if not (REPO / m.group(0)).exists():
                bad.append(f"{path.relative_to(REPO)}: {m.group(0)}: no such file")
    assert not bad, f"{len(bad)} paths to nothing:\n" + "\n".join(sorted(set(bad)))


# --------------------------------------------------------------------------- cited sections
# a section of a document under docs/ cited by its title: docs/design.md, "Chain conventions"
# (also 'Chain conventions', ("Chain conventions"), section "Chain conventions"), the title
# possibly broken across lines, comment markers or a Python string's continuation
CITATION = re.compile(r"(?<![\w/.-])(docs/[\w/.-]+\.md)`*\)?(?:[,(]|\s|#)+(?:section )?([\"'])")
# what a title spread over lines looks like once joined: 'measured, "\n    "not built'
CONTINUED = re.compile(r"[\"']\s*\n\s*[\"']|\s*\n\s*(?:#\s*)?")
FENCE = re.compile(r"^```.*?^```", re.M | re.S)
# this file's own examples of stale citations
CITES_ON_PURPOSE = {"tests/test_layout.py"}


def headings(path: Path) -> set[str]:
    """The titles a section of a Markdown file is cited by: each heading's (outside fenced
    code), and its short form, the part before a comma, colon or parenthesis ("Benchmarks" for
    "Benchmarks, the performance history and CI")."""
    text = FENCE.sub("", path.read_text())
    titles = {line.lstrip("#").strip() for line in text.splitlines() if line.startswith("#")}
    return titles | {re.split(r",|:| \(", t)[0] for t in titles}


def stale_citations(text: str) -> list[str]:
    """The citations in ``text`` whose title is no heading of the cited document: the title must
    be followed by the quote it opened with."""
    bad = []
    for m in CITATION.finditer(text):
        doc = REPO / m.group(1)
        quote, rest = m.group(2), CONTINUED.sub(" ", text[m.end():m.end() + 300])
        rest = re.sub(r" +", " ", rest)
        if not doc.is_file():
            bad.append(f"{m.group(1)}: no such document")
        elif not any(rest.startswith(title + quote) for title in headings(doc)):
            bad.append(f"{m.group(1)}, {quote}{rest[:50]}...")
    return bad


def test_a_stale_citation_is_found():
    assert stale_citations('docs/design.md, "Chain conventions"') == []
    assert stale_citations("(docs/design.md, 'The paper's numbers')") == []
    assert stale_citations('docs/design.md,\n    # "Chain\n    # conventions")') == []
    assert stale_citations("docs/design.md, 'Adaptive resolution: measured, \"\n    \"not "
                           "built'") == []
    assert stale_citations("docs/design.md's decisions, docs/notes/README.md") == []
    assert stale_citations('docs/design.md, "Chain rules"') == ['docs/design.md, "Chain rules"...']
    assert stale_citations('docs/nothing.md, "Layers"') == ["docs/nothing.md: no such document"]


def test_every_cited_section_is_a_heading_of_the_cited_document():
    """Code, tests and documents cite a section of a document under docs/ by its title
    (``docs/design.md, "Chain conventions"``): a section renamed, or moved to a note, would
    leave the citation pointing at nothing."""
    bad = [f"{path.relative_to(REPO)}: {cited}" for path in text_files()
           if str(path.relative_to(REPO)) not in CITES_ON_PURPOSE
           for cited in stale_citations(path.read_text())]
    assert not bad, f"{len(bad)} citations of no section:\n" + "\n".join(sorted(set(bad)))


DOC_PATH = re.compile(r"(?<![\w./-])docs/[\w/.-]*\w\.md\b")


def test_every_document_a_file_names_exists():
    """docs/design.md points to its measurements as dated notes (docs/notes/<date>-<topic>.md),
    and code and documents point to both: a note renamed would leave the pointer dangling."""
    bad = [f"{path.relative_to(REPO)}: {m.group(0)}" for path in text_files()
           if str(path.relative_to(REPO)) not in CITES_ON_PURPOSE
           for m in DOC_PATH.finditer(path.read_text()) if not (REPO / m.group(0)).is_file()]
    assert not bad, f"{len(bad)} paths to no document:\n" + "\n".join(sorted(set(bad)))
