"""A sweep on a Dask cluster as a user's cluster runs it: a scheduler and two workers, each an
interpreter of its own started by distributed's own commands (``dask scheduler``, ``dask
worker``), on localhost. A worker killed (SIGKILL) while it holds runs loses only those runs,
which the scheduler gives to the other worker: the rows and samples equal the local pool's. A
worker that cannot import the project, or runs other code, is refused by name before any run; a
scheduler that goes away is a named error, and the runs that came back are kept.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pandas as pd
import pytest

from redysim.harness.spec import RunSpec
from redysim.harness.store import parquet_files, read_parquet
from redysim.harness.sweep import RUNS_DIR, SAMPLES_FILE, SweepError, run_sweep

pytestmark = pytest.mark.slow
distributed = pytest.importorskip("distributed")

DASK = Path(sys.executable).with_name("dask")  # distributed's command, in this venv
START_S = 90  # a scheduler's file or a worker's registration (a busy 2-core machine)
# what differs between two runs of the same spec (the process, the clock, the machine)
VOLATILE = ["cpu_s", "wall_s", "jit_s", "build_s", "peak_rss_mib", "python", "numpy", "scipy",
            "numba", "redysim", "machine", "cpu", "git_commit", "engine_version", "date",
            "executable", "cost_s", "cost_spread", "sample_cpu_s", "rhs_s", "work_s"]
# runs of about a second each (a 125-link chain by ode45): long enough to be killed inside
SPECS = [RunSpec(case="RE-U125-L1", t_end=t, sample=t / 4, rtol=rtol)
         for t in (0.08, 0.1) for rtol in (1e-6, 1e-8, 1e-10)]


class Cluster:
    """A scheduler and named workers, each its own process group (killed at the end)."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.procs: dict[str, subprocess.Popen] = {}
        self.env = {**os.environ, "REDYSIM_THREADS": "1", "PYTHONDONTWRITEBYTECODE": "1"}
        scheduler_file = folder / "scheduler.json"
        self._start("scheduler", "scheduler", "--scheduler-file", str(scheduler_file),
                    "--host", "127.0.0.1", "--port", "0", "--no-dashboard")
        deadline = time.monotonic() + START_S
        while not scheduler_file.is_file():
            self._alive("scheduler")
            assert time.monotonic() < deadline, self.log("scheduler")
            time.sleep(0.1)
        self.address = json.loads(scheduler_file.read_text())["address"]

    def _start(self, name: str, *args: str, env: dict | None = None) -> None:
        with open(self.folder / f"{name}.log", "w") as log:
            self.procs[name] = subprocess.Popen(
                [str(DASK), *args], stdout=log, stderr=subprocess.STDOUT, cwd=self.folder,
                env=env or self.env, start_new_session=True)

    def _alive(self, name: str) -> None:
        assert self.procs[name].poll() is None, f"{name} exited: {self.log(name)}"

    def log(self, name: str) -> str:
        return (self.folder / f"{name}.log").read_text()[-3000:]

    def worker(self, name: str, *extra: str, env: dict | None = None) -> None:
        """A worker process (no nanny: killing it kills the worker), one thread."""
        self._start(name, "worker", self.address, "--name", name, "--nthreads", "1",
                    "--no-nanny", "--no-dashboard", "--host", "127.0.0.1", *extra, env=env)

    def wait_for(self, names: set[str]) -> None:
        with distributed.Client(self.address, timeout=START_S) as client:
            deadline = time.monotonic() + START_S
            while names - {w["name"] for w in client.scheduler_info()["workers"].values()}:
                for name in names:
                    self._alive(name)
                assert time.monotonic() < deadline, [self.log(n) for n in names]
                time.sleep(0.1)

    def kill(self, name: str) -> None:
        os.killpg(self.procs[name].pid, signal.SIGKILL)
        self.procs[name].wait(timeout=30)

    def close(self) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=30)


@pytest.fixture
def cluster(tmp_path):
    c = Cluster(tmp_path)
    try:
        yield c
    finally:
        c.close()


def in_thread(fn) -> tuple[threading.Thread, dict]:
    box: dict = {}

    def run():
        try:
            box["value"] = fn()
        except BaseException as exc:  # (handed to the test's thread)
            box["error"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread, box


def held_by(client, name: str) -> list[str]:
    """The keys the scheduler has given the worker named ``name`` (running or next)."""
    names = {addr: w["name"] for addr, w in client.scheduler_info()["workers"].items()}
    return [str(k) for addr, keys in client.processing().items() if names.get(addr) == name
            for k in keys]


def test_a_killed_worker_loses_only_its_runs_and_the_results_equal_the_local_pool(cluster,
                                                                                 tmp_path):
    local = run_sweep(SPECS, tmp_path / "pool", workers=2, progress=False)
    assert (local["status"] == "ok").all(), local[["run_id", "status", "reason"]]
    cluster.worker("a")
    cluster.worker("b")
    cluster.wait_for({"a", "b"})
    out = tmp_path / "dask"
    thread, box = in_thread(lambda: run_sweep(SPECS, out, dask=cluster.address,
                                              progress=False))
    with distributed.Client(cluster.address, timeout=START_S) as watch:
        deadline = time.monotonic() + START_S
        while not (held := held_by(watch, "a")):
            assert thread.is_alive() and time.monotonic() < deadline, box
            time.sleep(0.02)
        time.sleep(0.2)  # (inside the run: each takes about a second)
        done_before = len(parquet_files(out / RUNS_DIR))
        cluster.kill("a")
    thread.join(timeout=600)
    assert not thread.is_alive() and "error" not in box, box
    runs = box["value"]
    assert done_before < len(SPECS)  # the worker was killed in the middle of the study
    assert (runs["status"] == "ok").all(), runs[["run_id", "status", "reason"]]
    assert {k.removeprefix("redysim-run-") for k in held} <= set(runs["run_id"])
    pd.testing.assert_frame_equal(local.drop(columns=VOLATILE), runs.drop(columns=VOLATILE))
    pd.testing.assert_frame_equal(read_parquet(tmp_path / "pool" / SAMPLES_FILE),
                                  read_parquet(out / SAMPLES_FILE))
    assert "Remove worker" in cluster.log("scheduler") or "lost" in cluster.log("scheduler")


def refused(cluster: Cluster, tmp_path: Path, name: str, setup: str, says: str) -> None:
    """A worker whose start runs ``setup`` (the body of a Dask preload's ``dask_setup``) is
    refused by name, matching ``says``, before its result is kept: nothing is run."""
    (tmp_path / f"{name}.py").write_text(f"import pathlib, sys\ndef dask_setup(worker):\n"
                                         f"{setup}\n")
    cluster.worker(name, "--preload", name, env={**cluster.env, "PYTHONPATH": str(tmp_path)})
    cluster.wait_for({name})
    with pytest.raises(SweepError, match=r"worker = 'tcp://.*': " + says):
        run_sweep(SPECS[:1], tmp_path / name, dask=cluster.address, progress=False)
    cluster.kill(name)
    assert not parquet_files(tmp_path / name / RUNS_DIR)


def test_a_worker_of_other_code_or_without_the_project_is_refused_by_name(cluster, tmp_path):
    refused(cluster, tmp_path, "other",
            "    import redysim.harness.provenance as p\n"
            "    p.code_digest = lambda: 'f' * 64  # another version of the project",
            r"runs other code \(code digest ffffffffffff, this checkout's")
    refused(cluster, tmp_path, "bare",
            "    for name in [m for m in sys.modules if m.split('.')[0] == 'redysim']:\n"
            "        del sys.modules[name]\n"
            "    sys.modules['redysim'] = None  # import redysim fails, as without the project",
            r"cannot run this project's code \(.*\): install this checkout on every worker")


def test_a_worker_blind_to_the_reference_cache_is_refused_by_name(cluster, tmp_path,
                                                                 monkeypatch):
    """A run reads the cached reference solution of its case (its error columns); a worker on
    a machine without the client's results folder would return rows without them: refused."""
    results = tmp_path / "shared-results"
    (results / "reference").mkdir(parents=True)
    monkeypatch.setenv("REDYSIM_RESULTS", str(results))
    refused(cluster, tmp_path, "blind",
            "    real = pathlib.Path.is_dir  # a machine without the client's results folder\n"
            "    pathlib.Path.is_dir = lambda self: ('shared-results' not in str(self)\n"
            "                                        and real(self))",
            r"does not see the reference cache .*shared-results/reference")


def test_a_scheduler_that_goes_away_is_named_and_the_runs_that_came_back_are_kept(cluster,
                                                                                 tmp_path):
    cluster.worker("a")
    cluster.wait_for({"a"})
    out = tmp_path / "dask"
    thread, box = in_thread(lambda: run_sweep(SPECS, out, dask=cluster.address,
                                              progress=False))
    deadline = time.monotonic() + START_S
    while not parquet_files(out / RUNS_DIR):  # a first run came back
        assert thread.is_alive() and time.monotonic() < deadline, box
        time.sleep(0.05)
    cluster.kill("scheduler")
    thread.join(timeout=600)
    assert not thread.is_alive()
    assert isinstance(box.get("error"), SweepError), box
    assert "the scheduler went away" in str(box["error"])
    kept = set(parquet_files(out / RUNS_DIR))
    assert 1 <= len(kept) < len(SPECS)
    again = run_sweep(SPECS, out, workers=2, progress=False)  # the rest, here
    assert (again["status"] == "ok").all() and again.attrs["ran"] == len(SPECS) - len(kept)


def test_a_reproduction_sends_its_sweeps_to_the_cluster_it_is_given(cluster, tmp_path,
                                                                    monkeypatch):
    """`python -m redysim.reports.reproduce --dask ADDRESS` (make reproduce DASK=ADDRESS): every
    run_sweep inside it goes to that cluster, also one given a pool size (the refinement
    studies'); outside the block, the local pool as before."""
    from redysim.harness import sweep
    from redysim.reports import reproduce

    seen: list = []
    monkeypatch.setattr(reproduce.Reproduction, "run",
                        lambda self, plan: seen.append(sweep._DASK_DEFAULT[0]) or 0)
    assert reproduce.main(["--build-only", "--results", str(tmp_path / "r"), "--out",
                           str(tmp_path / "o"), "--dask", cluster.address]) == 0
    assert seen == [cluster.address] and sweep._DASK_DEFAULT[0] is None
    cluster.worker("a")
    cluster.wait_for({"a"})
    used: list = []
    real = sweep._dask_results
    monkeypatch.setattr(sweep, "_dask_results",
                        lambda work, address, task: used.append(address) or real(work, address,
                                                                                 task))
    with sweep.dask_default(cluster.address):
        runs = run_sweep(SPECS[:2], tmp_path / "s", workers=2, progress=False)
    assert used == [cluster.address] and (runs["status"] == "ok").all()
    run_sweep(SPECS[2:3], tmp_path / "t", workers=1, progress=False)  # outside: the pool
    assert used == [cluster.address]
