"""The README's front door: every shell command of its ``sh`` blocks and its Python blocks run
as written, from the repository root, as a new user would run them (a subprocess each; the
Python blocks together, as one session, since the second uses the first's ``robot``).

A ``make`` line is not run (make reproduce and make test are the whole reproduction and the
whole suite): its target must exist in the Makefile. Results go to a temporary folder
(``REDYSIM_RESULTS``), never into the checkout. The commands that run every engine or a study
(compare) are slow; the others run in the fast stage. A command the README gains is
run by these tests at once: one that is neither a ``redysim`` nor a ``make`` line fails here,
to be added on purpose.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
README = (REPO / "README.md").read_text()
MAKEFILE = (REPO / "Makefile").read_text()
BIN = Path(sys.executable).parent  # the venv's: the `redysim` console script is beside python
SLOW = ("redysim compare",)  # every engine, every integrator: ~40 s (advise TALOS-FALL: ~7 s)


def blocks(language: str) -> list[str]:
    """The fenced blocks of README.md in ``language``, in order."""
    return re.findall(rf"^```{language}\n(.*?)^```", README, re.S | re.M)


def shell_commands() -> list[str]:
    """Every command line of the README's ``sh`` blocks: continuation lines joined, comments
    and blank lines dropped."""
    out = []
    for block in blocks("sh"):
        for line in block.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            if words:
                out.append(shlex.join(words))
    return out


COMMANDS = shell_commands()


def _env(tmp_path: Path) -> dict[str, str]:
    env = dict(os.environ, REDYSIM_RESULTS=str(tmp_path / "results"),
               PATH=f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}")
    env.pop("PYTHONPATH", None)  # the installed package, as a user has it
    return env


def _run(args, tmp_path: Path, *, shell: bool = False) -> subprocess.CompletedProcess:
    return subprocess.run(args, cwd=REPO, env=_env(tmp_path), shell=shell, text=True,
                          capture_output=True, timeout=3600)


def test_the_readme_has_commands_and_python():
    """What the other tests run is there: the shell commands and the Python blocks (a README
    rewritten into other fences would leave these tests nothing to run)."""
    assert len(COMMANDS) >= 5 and any(c.startswith("make ") for c in COMMANDS)
    assert len(blocks("python")) >= 2
    assert all(c.split()[0] in ("redysim", "make") for c in COMMANDS), \
        [c for c in COMMANDS if c.split()[0] not in ("redysim", "make")]


def _targets() -> set[str]:
    """The Makefile's targets, with its pattern rules' instances (table1 .. tableA2)."""
    names = set(re.findall(r"^([A-Za-z0-9_.-]+):", MAKEFILE, re.M))
    for line in re.findall(r"^\.PHONY:(.*)$", MAKEFILE, re.M):
        names.update(line.split())
    tables = re.search(r"^PAPER_TABLES\s*:=(.*)$", MAKEFILE, re.M)
    if tables:
        names.update(f"table{t}" for t in tables.group(1).split())
    return names


@pytest.mark.parametrize("command", [c for c in COMMANDS if c.startswith("make ")])
def test_make_lines_name_targets(command):
    targets = _targets()
    for word in shlex.split(command)[1:]:
        if not word.startswith("-") and "=" not in word:
            assert word in targets, f"README: {command!r}: no target {word!r} in the Makefile"


def _marks(command: str):
    return [pytest.mark.slow] if command.startswith(SLOW) else []


@pytest.mark.parametrize("command", [pytest.param(c, marks=_marks(c), id=c)
                                     for c in COMMANDS if c.startswith("redysim")])
def test_shell_command_runs_as_written(command, tmp_path):
    """The command, run from the repository root through a shell exactly as the README
    writes it, exits 0 and says something; nothing lands in the checkout."""
    before = _untracked()
    proc = _run(command, tmp_path, shell=True)
    assert proc.returncode == 0, f"{command}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    assert proc.stdout.strip(), command
    assert "Traceback" not in proc.stderr, proc.stderr
    assert _untracked() == before, f"{command} wrote into the checkout"


def test_python_blocks_run_as_written(tmp_path):
    """The README's Python blocks, one after another in one interpreter, from the repository
    root: no error, and the names the comments promise are there (checked at the end)."""
    code = "\n".join(blocks("python"))
    check = ("\nimport numpy as _np\n"
             "assert qdd.shape == (case.chain.n_dof,) and _np.isfinite(qdd).all()\n"
             "assert robot.n_v == 6 and abs(fall.t[-1] - 1.0) < 1e-12\n"
             "assert _np.asarray(run.observed['tool']).shape[0] == len(run.t)\n"
             "print('ok')\n")
    before = _untracked()
    proc = _run([sys.executable, "-c", code + check], tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip().endswith("ok")
    assert _untracked() == before, "the README's Python wrote into the checkout"


def _untracked() -> set[str]:
    """Files git does not track, ignored ones too (but the caches a run may write)."""
    out = subprocess.run(["git", "status", "--porcelain", "--ignored", "--untracked-files=all"],
                         cwd=REPO, text=True, capture_output=True).stdout
    return {line for line in out.splitlines()
            if not re.search(r"\.venv/|egg-info/|\.pytest_cache/|__pycache__/", line)}


def test_a_bare_robot_file_name_says_the_name_to_give(tmp_path):
    """The README's old form, a bare file name of example-robot-data, is refused (exit 2) with
    the form that works, not 'does not exist' alone."""
    from redysim.io.scenarios import robot_data_file

    if robot_data_file("ur5") is None:
        pytest.skip("example-robot-data is not installed")
    proc = _run(["redysim", "info", "ur5_robot.urdf"], tmp_path)
    assert proc.returncode == 2
    assert "example-robot-data:ur5" in proc.stderr and "Traceback" not in proc.stderr


def test_the_guides_closed_loops_example_runs_as_written(tmp_path):
    """docs/guide.md's closed-loops block, from the repository root (hold-out battery 6: it
    unpacked two values from forward_dynamics, which returns qdd alone)."""
    section = (REPO / "docs" / "guide.md").read_text().split("## Closed loops", 1)[1]
    code = re.search(r"^```python\n(.*?)^```", section, re.S | re.M).group(1)
    res = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True,
                         timeout=600, env={**os.environ, "REDYSIM_RESULTS": str(tmp_path)})
    assert res.returncode == 0, res.stderr[-2000:]
