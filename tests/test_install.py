"""What an install without extras can do, and where an installed redysim finds its data.

A base install (``pip install redysim``: numpy, scipy, numba) runs the ``redysim`` command on
the core: its help, the cases, a rope case simulated and printed, a URDF read. A command that
needs an extra (pyproject.toml's ``[project.optional-dependencies]``) refuses, naming the extra
to install, with exit code 2 and no traceback. A base install is made here by a subprocess in
which every package of the ``harness``, ``models`` and ``engines`` extras is missing (its
``sys.modules`` entry None: ``import`` raises ModuleNotFoundError and
:func:`importlib.util.find_spec` finds nothing, as for a package that is not installed);
``.ci/install-check`` does the same with a real wheel in a fresh venv.

An installed redysim has no repository around it: its data (cases, robots, sweeps) are package
data, found through the package and never through a folder next to a module's file.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import tomllib
from fnmatch import fnmatch
from pathlib import Path

import pytest

from redysim.harness import BLAS_THREAD_VARIABLES, cli

REPO = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())
OPTIONAL = PYPROJECT["project"]["optional-dependencies"]
IMPORT_NAME = {"pin": "pinocchio", "drake": "pydrake"}  # distribution -> module, where they differ


def requirement_name(req: str) -> str:
    """``"pandas>=2.2"`` -> ``"pandas"``."""
    for i, ch in enumerate(req):
        if not (ch.isalnum() or ch in "-_."):
            return req[:i]
    return req


def extra_modules(extra: str) -> list[str]:
    """The import names of the packages an extra installs."""
    names = (requirement_name(r) for r in OPTIONAL[extra])
    return [IMPORT_NAME.get(n, n).replace("-", "_") for n in names]


# what a base install lacks: every package of these extras (and dask, distributed's core)
MISSING = sorted({m for e in ("harness", "models", "engines") for m in extra_modules(e)}
                 | {"dask"})

BASE_INSTALL = """\
import sys
for name in {missing!r}:
    sys.modules[name] = None  # as if not installed
from redysim.harness.cli import main
sys.exit(main(sys.argv[1:]))
"""

URDF = """<robot name="two">
  <link name="base"/>
  <link name="l1"><inertial><mass value="1"/><origin xyz="0.5 0 0"/>
    <inertia ixx="0.01" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l2"><inertial><mass value="1"/><origin xyz="0.5 0 0"/>
    <inertia ixx="0.01" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="continuous"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/></joint>
  <joint name="j2" type="continuous"><parent link="l1"/><child link="l2"/>
    <origin xyz="1 0 0"/><axis xyz="0 0 1"/></joint>
</robot>
"""


# as a user's shell: no BLAS thread count set (importing redysim.harness, as this module does,
# sets one in this process's environment, which a child would inherit)
ENV = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}


def base_install(*argv: str, cwd: Path) -> subprocess.CompletedProcess:
    """``redysim ARGV`` in a process without the extras, run from ``cwd`` (not the checkout)."""
    code = BASE_INSTALL.format(missing=MISSING)
    return subprocess.run([sys.executable, "-c", code, *argv], cwd=cwd, env=ENV,
                          capture_output=True, text=True)


def test_the_base_install_lacks_the_extras(tmp_path):
    """The simulated base install is one: pandas, threadpoolctl and mujoco do not import."""
    code = ("import importlib.util, sys\n"
            f"for name in {MISSING!r}: sys.modules[name] = None\n"
            "print([importlib.util.find_spec(m) for m in ('pandas', 'threadpoolctl', 'mujoco')])\n"
            "import pandas\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                         text=True)
    assert out.stdout.strip() == "[None, None, None]"
    assert "ModuleNotFoundError" in out.stderr and out.returncode == 1
    assert {"pandas", "pyarrow", "threadpoolctl", "mujoco", "pinocchio"} <= set(MISSING)


def test_a_base_install_prints_its_help_and_cases(tmp_path):
    out = base_install("--help", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "simulate" in out.stdout and "sweep" in out.stdout
    out = base_install("cases", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "STUDY-R3 " in out.stdout and "RE-U125-L1 " in out.stdout


def test_a_base_install_simulates_a_rope_case(tmp_path):
    """The core runs a rope case and prints it, without pandas (only --out needs it)."""
    out = base_install("simulate", "STUDY-R3", "--t-end", "0.01", "--sample", "0.005",
                       cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "status        ok" in out.stdout and "E(0)" in out.stdout
    table = out.stdout.split("COM z [m]")[1].split()  # t, delta_M, tip x y z, COM x y z
    assert [float(t) for t in table[::8]] == [0.0, 0.005, 0.01]  # the samples' times
    assert list(tmp_path.iterdir()) == []  # printed, nothing written


def test_a_base_install_reads_a_urdf(tmp_path):
    """URDF is read by redysim itself: no extra needed."""
    (tmp_path / "two.urdf").write_text(URDF)
    out = base_install("info", "two.urdf", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "2 bodies" in out.stdout and "j2" in out.stdout


# argv, the extra it needs
NEEDS_AN_EXTRA = {
    "sweep": (["sweep", str(REPO / "sweeps" / "smoke.toml")], "harness"),
    "advise": (["advise", "fall", "--tip-tol", "0.01"], "harness"),
    "advise-hanging": (["advise", "hanging", "--modes", "2", "--freq-tol", "0.1"], "harness"),
    "simulate --out": (["simulate", "STUDY-R3", "--t-end", "0.01", "--out", "tip.csv"],
                       "harness"),
    "simulate robot --out": (["simulate", "two.urdf", "--t-end", "0.01", "--out", "f.parquet"],
                             "harness"),
    "simulate --engine": (["simulate", "STUDY-R3", "--t-end", "0.01", "--engine", "mujoco"],
                          "engines"),
    "info MJCF": (["info", str(REPO / "tests" / "models" / "humanoid.xml")], "models"),
}


@pytest.mark.parametrize("command", NEEDS_AN_EXTRA)
def test_a_command_that_needs_an_extra_refuses_naming_it(command, tmp_path):
    argv, extra = NEEDS_AN_EXTRA[command]
    (tmp_path / "two.urdf").write_text(URDF)
    out = base_install(*argv, cwd=tmp_path)
    assert out.returncode == 2, (out.stdout, out.stderr)
    assert f"pip install 'redysim[{extra}]'" in out.stderr, out.stderr
    assert "Traceback" not in out.stderr, out.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["two.urdf"]  # refused before the run


def test_every_optional_package_names_its_extra():
    """The command's table of which extra installs what agrees with pyproject.toml."""
    for extra in ("harness", "models", "engines"):
        for module in extra_modules(extra):
            assert module in cli.EXTRA_OF, module
            assert module in extra_modules(cli.EXTRA_OF[module]), (module, cli.EXTRA_OF[module])


# --------------------------------------------------------------------------- package data
def test_every_file_of_a_package_folder_ships():
    """Every folder that installs as a package (pyproject.toml's package-dir: cases/ ->
    redysim.case_files, ...) ships whole: each subfolder is a declared package and each file
    that is not Python matches its package's package-data patterns. The sweep files are one of
    them: the refinement studies and the reproduction read them from the installed package."""
    setup = PYPROJECT["tool"]["setuptools"]
    folders = {"redysim": "redysim", **setup["package-dir"]}
    assert "sweeps" in folders.values(), "sweeps/ is not installed as a package"
    packages, data = set(setup["packages"]), setup["package-data"]
    # the project's files: what git tracks and what it would (not what it ignores: the report
    # that `make reproduce` writes into reports/out/, caches), so that the test holds after a
    # reproduction as on a clean checkout
    project = set(subprocess.run(["git", "-C", str(REPO), "ls-files", "-co", "--exclude-standard"],
                                 capture_output=True, text=True, check=True).stdout.splitlines())
    missing = []
    for package, folder in folders.items():
        for directory in [REPO / folder, *sorted((REPO / folder).rglob("*"))]:
            if not directory.is_dir() or "__pycache__" in directory.parts:
                continue
            files = [p for p in directory.iterdir() if p.is_file() and p.suffix != ".pyc"
                     and str(p.relative_to(REPO)) in project]
            name = ".".join((package, *directory.relative_to(REPO / folder).parts))
            if files and name not in packages:
                missing.append(f"{directory.relative_to(REPO)}/ (package {name} not declared)")
            for p in files:
                if p.suffix != ".py" and not any(fnmatch(p.name, g) for g in data.get(name, ())):
                    missing.append(f"{p.relative_to(REPO)} (no package-data pattern of {name})")
    assert not missing, "not in the wheel: " + ", ".join(missing)


def test_the_report_finds_the_dh_robots_wherever_its_module_lies(tmp_path, monkeypatch):
    """Installed, reports/robots.py lies in site-packages/redysim/reports/, with no cases/
    folder beside it: it finds the DH robot files as package data (redysim.case_files.robots),
    not through a path relative to its own file. A copy of the module outside the checkout
    must list the same robots as the checkout's cases/robots/."""
    copy = tmp_path / "site-packages" / "redysim" / "reports" / "robots.py"
    copy.parent.mkdir(parents=True)
    shutil.copy(REPO / "reports" / "robots.py", copy)
    spec = importlib.util.spec_from_file_location("robots_installed_elsewhere", copy)
    robots = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(robots)
    monkeypatch.setattr(robots, "ROBOTS", ())  # example-robot-data's URDFs: another package
    found = sorted(label.rsplit("/", 1)[1].rstrip(")") for label, _, _ in robots.models())
    assert found == sorted(p.name for p in (REPO / "cases" / "robots").glob("*.toml"))
