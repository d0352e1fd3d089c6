"""The package's layers depend one way: core <- references <- harness <- reports.

The core (``redysim/*.py``, ``redysim/_kernels``) imports none of the others; the engine adapters
(``references/``) import only the core; the harness (``harness/``: runs, sweeps, the CLI) imports
the core and the adapters, never the reports; and no two modules import each other, directly or
round a longer cycle, not even from inside a function. Read from the source with :mod:`ast`, so a
lazy import inside a function counts as much as one at the top.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
# installed name -> folder in the repository (pyproject.toml's package-dir)
LAYERS = {"redysim": REPO / "redysim", "redysim.references": REPO / "references",
          "redysim.harness": REPO / "harness", "redysim.reports": REPO / "reports"}
ORDER = ["redysim", "redysim.references", "redysim.harness", "redysim.reports"]


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


def test_the_walk_sees_the_project():
    """The checks above read something: every layer has modules, and a known edge is found."""
    assert all(any(layer(m) == p for m in MODULES) for p in ORDER)
    assert "redysim.harness.spec" in GRAPH["redysim.harness.run"]
