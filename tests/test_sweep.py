"""Sweeps: sweep files and their errors, resume after kill -9, Dask equals the local pool,
failed runs recorded, atomic writes, and the ``redysim`` command line."""

from __future__ import annotations

import hashlib
import json
import os
import random
import shlex
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pandas as pd
import pytest

from redysim.harness.cli import main
from redysim.harness.spec import RunSpec
from redysim.harness.store import (
    FILE_MODE,
    TEMP_PREFIX,
    TEMP_SUFFIX,
    parquet_files,
    read_parquet,
    remove_temp_files,
    write_parquet_atomic,
)
from redysim.harness.sweep import (
    CLAIMS_DIR,
    DAMAGED_DIR,
    DIED,
    PLAN_FILE,
    RUNS_DIR,
    RUNS_FILE,
    SAMPLES_DIR,
    SAMPLES_FILE,
    Claims,
    SweepError,
    _pool_results,
    _Work,
    collect,
    failed_row,
    load_sweep,
    run_sweep,
)

REPO = Path(__file__).resolve().parents[1]
PYTHON = sys.executable
# Columns that legitimately differ between two executions of the same run.
VOLATILE = ["cpu_s", "wall_s", "jit_s", "build_s", "peak_rss_mib", "python", "numpy", "scipy",
            "numba", "redysim", "machine", "cpu", "git_commit", "engine_version", "date",
            "executable", "cost_s", "cost_spread", "sample_cpu_s", "rhs_s", "work_s"]
TINY = [RunSpec(case="STUDY-R3", t_end=0.2, sample=0.05),
        RunSpec(case="RE-U125-L1", t_end=0.01, sample=0.005),
        RunSpec(case="STUDY-R3", t_end=0.2, sample=0.05, integrator="rk4", h=0.01),
        RunSpec(case="RE-U125-L1", t_end=0.01, sample=0.005, integrator="dop853", rtol=1e-6,
                atol=1e-8)]


def write(tmp_path: Path, text: str, name: str = "sweep.toml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def subprocess_env() -> dict:
    """The environment for a child Python that must import this checkout."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get(
        "PYTHONPATH", "")])}


# --------------------------------------------------------------------------- (a) sweep files
def test_expansion_cross_product_product_tables_and_extras(tmp_path):
    case_file = write(tmp_path, (REPO / "cases" / "STUDY-R3.toml").read_text(), "mine.toml")
    path = write(tmp_path, """
        [sweep]
        name = "demo"
        cases = ["STUDY-R3", "mine.toml"]
        methods = ["rge-a", "ge-n"]
        integrators = ["ode45", "rk4"]
        rtols = [1e-4, 1e-6]
        atol_ratio = 1e-2
        h = [1e-3]
        t_end = 0.5
        sample = 0.1
        max_cpu_s = 30

        [[sweep.product]]
        cases = ["RE-U125-L1"]
        engines = ["mujoco", "dart"]
        rtols = [1e-5]
        atols = [1e-9]
        integrators = ["dop853"]

        [[sweep.extra]]
        case = "STUDY-R10"
        integrator = "scipy-Radau"
        rtol = 1e-8
        atol = 1e-10

        [[sweep.extra]]            # the same run as one of the cross product: run once
        case = "STUDY-R3"
        integrator = "rk4"
        h = 1e-3
        """)
    sweep = load_sweep(path)
    assert sweep.name == "demo"
    # 2 cases x 2 methods x (ode45 x 2 rtols + rk4 x 1 h); 2 engines; 1 new extra run
    assert len(sweep.specs) == 2 * 2 * 3 + 2 + 1
    main_runs, product_runs, extra = sweep.specs[:12], sweep.specs[12:14], sweep.specs[14:]
    assert len({s.run_id for s in sweep.specs}) == len(sweep.specs)
    first = main_runs[0]
    assert (first.case, first.engine, first.method, first.integrator) == (
        "STUDY-R3", "redysim", "rge-a", "ode45")
    assert (first.rtol, first.atol, first.h) == (1e-4, 1e-6, 0.0)  # 1e-4 * 1e-2 rounded: 1e-06
    assert (first.t_end, first.sample, first.max_cpu_s) == (0.5, 0.1, 30.0)
    assert main_runs[6].case == str(case_file.resolve())
    stepped = [s for s in main_runs if s.integrator == "rk4"]
    assert len(stepped) == 4 and all(s.h == 1e-3 for s in stepped)
    for s in product_runs:  # engines take no method; product inherits t_end from [sweep]
        assert (s.case, s.method, s.integrator, s.rtol, s.atol, s.t_end) == (
            "RE-U125-L1", "", "dop853", 1e-5, 1e-9, 0.5)
    assert [s.engine for s in product_runs] == ["mujoco", "dart"]
    assert extra[0] == RunSpec(case="STUDY-R10", integrator="scipy-Radau", rtol=1e-8, atol=1e-10,
                               t_end=0.5, sample=0.1, max_cpu_s=30.0)


def test_example_sweep_files_load():
    smoke = load_sweep(REPO / "sweeps" / "smoke.toml")
    assert len(smoke.specs) == 8
    wp = load_sweep(REPO / "sweeps" / "work-precision-RE-U125-L1.toml")
    engines = {s.engine for s in wp.specs}
    assert engines == {"redysim", "mujoco", "dart", "pinocchio-aba", "pinocchio-aba-ryrz",
                       "pinocchio-crba", "exudyn"}
    assert {s.integrator for s in wp.specs if s.engine != "redysim"} == {"ode45", "native"}
    assert wp.reference and not smoke.reference


def test_perturbs_multiply_into_runs_from_shifted_initial_states(tmp_path):
    path = write(tmp_path, """\
        [sweep]
        name = "ens"
        cases = ["STUDY-R3"]
        rtols = [1e-4, 1e-6]
        perturbs = [0, 1e-13, 2e-13]
        """)
    specs = load_sweep(path).specs
    assert len(specs) == 6 and len({s.run_id for s in specs}) == 6
    assert sorted({s.perturb for s in specs}) == [0, 1e-13, 2e-13]
    # perturb = 0 is the case's own run: the same id as a sweep that never mentions perturbs
    plain = load_sweep(write(tmp_path, '[sweep]\nname = "p"\ncases = ["STUDY-R3"]\n'
                                       'rtols = [1e-4, 1e-6]\n', "plain.toml")).specs
    assert {s.run_id for s in plain} == {s.run_id for s in specs if s.perturb == 0}
    ens = load_sweep(REPO / "sweeps" / "drift-ensemble.toml").specs
    assert len(ens) == 5 * 16 + 8 + 4 and all(s.perturb <= 1.5e-12 for s in ens)


BAD = {
    "unknown field": ('rtol = [1e-4]', "sweep.rtol", "[0.0001]", "unknown field"),
    "wrong type": ('cases = "STUDY-R3"', "sweep.cases", "'STUDY-R3'", "must be a list"),
    "empty list": ('cases = ["STUDY-R3"]\nrtols = []', "sweep.rtols", "[]", "must not be empty"),
    "negative tolerance": ('cases = ["STUDY-R3"]\nrtols = [1e-4, -1e-6]', "sweep.rtols[1]",
                           "-1e-06", "> 0"),
    "unknown integrator": ('cases = ["STUDY-R3"]\nintegrators = ["ode45", "euler"]',
                           "sweep.integrators[1]", "'euler'", "unknown integrator"),
    "unknown case": ('cases = ["STUDY-R3", "STUDY-R4"]', "sweep.cases[1]", "'STUDY-R4'",
                     "no such case"),
    "unknown engine": ('cases = ["STUDY-R3"]\nengines = ["bullet"]', "sweep.engines[0]",
                       "'bullet'", "unknown engine"),
    "fixed step without h": ('cases = ["STUDY-R3"]\nintegrators = ["rk4"]', "sweep.h", None,
                             "needs step sizes"),
    "atols unpaired": ('cases = ["STUDY-R3"]\nrtols = [1e-4, 1e-6]\natols = [1e-6]',
                       "sweep.atols", "[1e-06]", "pair with rtols"),
    "bad number": ('cases = ["STUDY-R3"]\nt_end = "1 s"', "sweep.t_end", "'1 s'",
                   "must be a number"),
    "negative perturbation": ('cases = ["STUDY-R3"]\nperturbs = [0, -1e-13]',
                              "sweep.perturbs[1]", "-1e-13", ">= 0"),
    "bad extra": ('cases = ["STUDY-R3"]\n[[sweep.extra]]\ncase = "STUDY-R3"\nrtols = 1e-3',
                  "sweep.extra[0].rtols", "0.001", "unknown field"),
    "rtol below the floor": ('cases = ["STUDY-R3"]\nrtols = [1e-300]', "sweep.rtols", "1e-300",
                             "must be at least"),
    "step to an adaptive": ('cases = ["STUDY-R3"]\n[[sweep.extra]]\ncase = "STUDY-R3"\n'
                            'integrator = "ode45"\nh = 1e-3', "sweep.extra[0].h", "0.001",
                            "fixed-step integrator"),
    "h for adaptive integrators only": ('cases = ["STUDY-R3"]\nintegrators = ["ode45"]\n'
                                        'h = [1e-3]', "sweep.h", "[0.001]",
                                        "only fixed-step integrators take a step h"),
    "h for a product of adaptive integrators": ('cases = ["STUDY-R3"]\n[[sweep.product]]\n'
                                                'integrators = ["ode45"]\nh = [1e-3]',
                                                "sweep.product[0].h", "[0.001]",
                                                "only fixed-step integrators take a step h"),
    "samples past the cap": ('cases = ["STUDY-R3"]\nsample = 1e-9', "sweep.sample", "1e-09",
                             "at most 10,000,000"),
    "name is a path": ('name = "/tmp/elsewhere"\ncases = ["STUDY-R3"]', "sweep.name",
                       "'/tmp/elsewhere'", "plain folder name"),
    "name climbs out": ('name = "../up"\ncases = ["STUDY-R3"]', "sweep.name", "'../up'",
                        "plain folder name"),
    "a name for a file": ('cases = ["mine"]', "sweep.cases[0]", "'mine'", "./mine.toml"),
}


@pytest.mark.parametrize("name", BAD)
def test_bad_sweep_file_names_file_field_and_value(tmp_path, name):
    body, field, value, problem = BAD[name]
    path = write(tmp_path, "[sweep]\n" + body + "\n")
    with pytest.raises(SweepError) as info:
        load_sweep(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: {field}"), msg
    if value is not None:
        assert f"{field} = {value}:" in msg, msg
    assert problem in msg, msg


def test_bad_sweep_file_on_the_command_line_exits_2_without_traceback(tmp_path, capsys):
    path = write(tmp_path, '[sweep]\ncases = ["STUDY-R3"]\nrtols = [0]\n')
    assert main(["sweep", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.strip() == f"redysim: error: {path}: sweep.rtols[0] = 0.0: must be a finite " \
                          "number > 0"
    assert main(["sweep", str(tmp_path / "missing.toml")]) == 2
    assert "does not exist" in capsys.readouterr().err
    syntax = write(tmp_path, "[sweep\n", "syntax.toml")
    assert main(["sweep", str(syntax)]) == 2
    assert "<toml syntax>" in capsys.readouterr().err


def test_a_sweep_takes_the_case_s_settings_and_reruns_an_edited_case(tmp_path):
    """A run left to the case takes its [simulation] integrator and tolerances; edit the case
    file and the resumed sweep runs it again (it reported the old 5-link results as done)."""
    case = write(tmp_path, (REPO / "cases" / "STUDY-R3.toml").read_text()
                 .replace('integrator = "ode45"', 'integrator = "dop853"')
                 .replace("rtol = 1e-4", "rtol = 1e-7"), "mine.toml")
    path = write(tmp_path, """
        [sweep]
        name = "edited"
        cases = ["mine.toml"]
        t_end = 0.1
        sample = 0.05
        """)
    (spec,) = load_sweep(path).specs
    assert (spec.integrator, spec.rtol, spec.atol) == ("dop853", 1e-7, 1e-6)
    out = tmp_path / "out"
    first = run_sweep(load_sweep(path).specs, out, progress=False)
    # result files get the umask's mode (readable by others sharing the folder), not mkstemp's
    # private 0600
    assert all(p.stat().st_mode & 0o777 == FILE_MODE for p in out.rglob("*.parquet"))
    assert first["n_dof"].tolist() == [3] and first["integrator"].tolist() == ["dop853"]
    case.write_text(case.read_text().replace("links = 3", "links = 5"))
    again = run_sweep(load_sweep(path).specs, out, progress=False)
    assert again["n_dof"].tolist() == [5] and again["run_id"].tolist() != first["run_id"].tolist()


# --------------------------------------------------------------------------- (b) kill -9
@pytest.mark.slow
def test_sweep_killed_with_sigkill_resumes_without_duplicates(tmp_path):
    """Kill the whole process group (the CLI and its pool workers) once some runs are saved.

    Runs are submitted in plan order, at most ``workers`` at a time; so every run finished before
    the kill lies among the first (finished + workers) planned runs, and the resumed sweep redoes
    only the (at most ``workers``) runs that were in flight.
    """
    workers = 2
    rtols = ", ".join(f"{k}e-7" for k in range(1, 11))
    path = write(tmp_path, f"""
        [sweep]
        name = "kill"
        cases = ["RE-U125-L1"]
        rtols = [{rtols}]
        t_end = 0.1
        sample = 0.01
        """)
    planned = [s.run_id for s in load_sweep(path).specs]
    out = tmp_path / "out"
    cmd = [PYTHON, "-m", "redysim.harness.cli", "sweep", str(path), "--out", str(out), "--workers",
           str(workers), "--no-progress"]
    proc = subprocess.Popen(cmd, cwd=REPO, env=subprocess_env(), start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while len(parquet_files(out / RUNS_DIR)) < 2:
            assert proc.poll() is None, "the sweep ended before it could be killed"
            assert time.monotonic() < deadline, "no run finished within 60 s"
            time.sleep(0.005)
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    before = {k: (p.stat().st_ino, p.stat().st_mtime_ns)
              for k, p in parquet_files(out / RUNS_DIR).items()}
    assert 2 <= len(before) < len(planned)
    assert max(planned.index(k) for k in before) < len(before) + workers

    res = subprocess.run(cmd, cwd=REPO, env=subprocess_env(), capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 0, res.stderr
    assert f"10 runs, {len(before)} already done" in res.stdout
    after = parquet_files(out / RUNS_DIR)
    assert sorted(after) == sorted(planned)
    for k, stamp in before.items():  # finished runs were not redone
        assert (after[k].stat().st_ino, after[k].stat().st_mtime_ns) == stamp
    assert sorted(parquet_files(out / SAMPLES_DIR)) == sorted(planned)
    runs = read_parquet(out / RUNS_FILE)
    assert runs["run_id"].tolist() == planned and (runs["status"] == "ok").all()
    samples = read_parquet(out / SAMPLES_FILE)
    assert samples.groupby("run_id").size().to_dict() == {k: 11 for k in planned}
    assert not list(out.rglob(f"{TEMP_PREFIX}*{TEMP_SUFFIX}"))
    assert not list((out / CLAIMS_DIR).iterdir())  # every claim released


# --------------------------------------------------------------------------- (c) Dask
@pytest.mark.slow
def test_dask_local_cluster_gives_the_same_rows_as_the_local_pool(tmp_path):
    pool = run_sweep(TINY, tmp_path / "pool", workers=2, progress=False)
    dask = run_sweep(TINY, tmp_path / "dask", dask="local", progress=False)
    assert pool["run_id"].tolist() == [s.run_id for s in TINY]
    assert (pool["status"] == "ok").all()
    pd.testing.assert_frame_equal(pool.drop(columns=VOLATILE), dask.drop(columns=VOLATILE))
    pd.testing.assert_frame_equal(read_parquet(tmp_path / "pool" / SAMPLES_FILE),
                                  read_parquet(tmp_path / "dask" / SAMPLES_FILE))


# --------------------------------------------------------------------------- (d) failures
@pytest.mark.slow
def test_failed_runs_are_recorded_with_their_reason_and_the_sweep_goes_on(tmp_path):
    specs = [RunSpec(case="RE-U125-L1", t_end=0.01, sample=0.005, energy_bound=1e-30),
             RunSpec(case="RE-U125-L1", t_end=0.5, sample=0.005, max_cpu_s=1e-6),
             *TINY[:2]]
    runs = run_sweep(specs, tmp_path, workers=1, progress=False)
    assert runs["status"].tolist() == ["failed", "failed", "ok", "ok"]
    assert runs["reason"].iloc[0].startswith("energy blow-up: |delta_M| = ")
    assert runs["reason"].iloc[1].startswith("time limit: max_cpu_s = 1e-06 s of CPU reached")
    assert runs["reason"].iloc[2:].tolist() == ["", ""]
    assert runs["n_samples"].iloc[0] >= 1  # the samples before the failure are kept
    # a second run of the sweep redoes nothing, failed runs included
    stamps = {k: p.stat().st_mtime_ns for k, p in parquet_files(tmp_path / RUNS_DIR).items()}
    again = run_sweep(specs, tmp_path, workers=1, progress=False)
    pd.testing.assert_frame_equal(again, runs)
    assert stamps == {k: p.stat().st_mtime_ns
                      for k, p in parquet_files(tmp_path / RUNS_DIR).items()}


def _task_that_crashes_or_raises(spec: RunSpec):
    """A stand-in for a worker's run: rk4 kills its process, dop853 raises, others succeed."""
    time.sleep(0.3)  # let the runs overlap, so that a crash takes an innocent run down with it
    if spec.integrator == "rk4":
        os._exit(3)
    if spec.integrator == "dop853":
        raise ArithmeticError("boom")
    return {**failed_row(spec, ""), "status": "ok"}, pd.DataFrame({"run_id": [spec.run_id]})


@pytest.mark.slow
def test_a_worker_that_dies_or_raises_fails_only_its_own_run(tmp_path):
    specs = [RunSpec(case="STUDY-R3"), RunSpec(case="STUDY-R3", integrator="rk4", h=0.01),
             RunSpec(case="STUDY-R3", rtol=1e-6), RunSpec(case="STUDY-R3", integrator="dop853")]
    work = _Work(specs, Claims(tmp_path), lambda spec: False)
    got = {spec.run_id: (summary, samples) for spec, summary, samples
           in _pool_results(work, 2, _task_that_crashes_or_raises)}
    assert sorted(got) == sorted(s.run_id for s in specs)
    status = {k: (row["status"], row["reason"]) for k, (row, _) in got.items()}
    assert status[specs[0].run_id] == ("ok", "")
    assert status[specs[1].run_id] == ("failed", DIED)
    assert status[specs[2].run_id] == ("ok", "")
    assert status[specs[3].run_id] == ("failed", "worker raised ArithmeticError('boom')")
    assert got[specs[1].run_id][1] is None
    assert got[specs[1].run_id][0]["transient"] and got[specs[3].run_id][0]["transient"]


def _task_pid(spec: RunSpec):
    """A stand-in for a worker's run that says which process ran it (rk4 kills its process)."""
    time.sleep(0.2)
    if spec.integrator == "rk4":
        os._exit(3)
    return {**failed_row(spec, str(os.getpid())), "status": "ok"}, None


def _pids(work_specs, tmp_path, workers=2):
    work = _Work(work_specs, Claims(tmp_path), lambda spec: False)
    return {spec.run_id: row for spec, row, _ in _pool_results(work, workers, _task_pid)}


@pytest.mark.slow
def test_sweeps_in_a_shared_pool_block_reuse_its_workers(tmp_path):
    """shared_pool: the second sweep runs in the first one's processes (no new interpreter per
    sweep); their CPU time is counted while they live; a worker's death renews the block's pool
    for the sweeps after it; outside a block, each sweep starts its own."""
    from redysim.harness.sweep import shared_pool, shared_pool_cpu_s

    first = [RunSpec(case="STUDY-R3", rtol=r) for r in (1e-3, 1e-4, 1e-5, 1e-6)]
    second = [RunSpec(case="STUDY-R3", rtol=r) for r in (1e-7, 1e-8)]
    crash = [RunSpec(case="STUDY-R3", integrator="rk4", h=0.01)]
    with shared_pool(2):
        a = {r["reason"] for r in _pids(first, tmp_path / "a").values()}
        assert shared_pool_cpu_s() > 0.0
        b = {r["reason"] for r in _pids(second, tmp_path / "b").values()}
        assert b <= a and len(a) == 2  # the same two processes
        assert [r["reason"] for r in _pids(crash, tmp_path / "c").values()] == [DIED]
        c = {r["reason"] for r in _pids(second, tmp_path / "d").values()}
        assert c and not c & a  # a new pool after the crash, kept for what follows
        assert {r["reason"] for r in _pids(first, tmp_path / "e").values()} <= c
    assert shared_pool_cpu_s() == 0.0  # the block's end ended its workers
    d = {r["reason"] for r in _pids(second, tmp_path / "f").values()}
    assert d and not d & (a | c)


def test_collect_orders_by_plan_and_ignores_unplanned_and_partial_runs(tmp_path):
    specs = TINY[:3]
    rows = {s.run_id: failed_row(s, "x") for s in specs}
    (tmp_path / PLAN_FILE).write_text(
        '{"runs": [' + ", ".join(f'{{"run_id": "{s.run_id}"}}' for s in specs[::-1]) + "]}")
    for s in specs[:2]:
        write_parquet_atomic(pd.DataFrame([rows[s.run_id]]),
                             tmp_path / RUNS_DIR / f"{s.run_id}.parquet")
        write_parquet_atomic(pd.DataFrame({"run_id": [s.run_id] * 2, "t": [0.0, 1.0]}),
                             tmp_path / SAMPLES_DIR / f"{s.run_id}.parquet")
    # samples without a summary (killed between the two writes) and a run of an older plan
    write_parquet_atomic(pd.DataFrame({"run_id": [specs[2].run_id], "t": [0.0]}),
                         tmp_path / SAMPLES_DIR / f"{specs[2].run_id}.parquet")
    stale = TINY[3]
    write_parquet_atomic(pd.DataFrame([failed_row(stale, "old")]),
                         tmp_path / RUNS_DIR / f"{stale.run_id}.parquet")
    runs = collect(tmp_path)
    assert runs["run_id"].tolist() == [specs[1].run_id, specs[0].run_id]
    samples = read_parquet(tmp_path / SAMPLES_FILE)
    assert samples["run_id"].tolist() == [specs[1].run_id] * 2 + [specs[0].run_id] * 2
    pd.testing.assert_frame_equal(read_parquet(tmp_path / RUNS_FILE), runs)


# --------------------------------------------------------------------------- (e) atomic writes
WRITER = """
import sys
import numpy as np, pandas as pd
from redysim.harness.store import write_parquet_atomic
n = int(sys.argv[2])
df = pd.DataFrame({"i": np.arange(n), "x": np.sin(np.arange(n)), "version": 0})
version = 0
while True:
    version += 1
    df["version"] = version
    df["x"] = np.sin(np.arange(n) + version)
    write_parquet_atomic(df, sys.argv[1])
    print(version, flush=True)
"""


@pytest.mark.slow
def test_a_writer_killed_mid_write_leaves_the_old_or_the_new_file(tmp_path):
    import numpy as np

    n = 400_000
    path = tmp_path / "big.parquet"
    rng = random.Random(7)
    torn_writes = 0
    for _ in range(5):
        proc = subprocess.Popen([PYTHON, "-c", WRITER, str(path), str(n)], cwd=REPO,
                                env=subprocess_env(), stdout=subprocess.PIPE, text=True)
        try:
            first = proc.stdout.readline()  # one whole version written: the file exists
            assert first, "the writer died before writing"
            time.sleep(rng.uniform(0.0, 0.4))
            proc.kill()
        finally:
            proc.wait(timeout=30)
        df = read_parquet(path)  # never torn: always reads
        assert len(df) == n
        version = int(df["version"].iloc[0])
        assert (df["version"] == version).all()
        np.testing.assert_array_equal(df["x"].to_numpy(), np.sin(np.arange(n) + version))
        torn_writes += remove_temp_files(tmp_path)
    assert not list(tmp_path.glob(f"*{TEMP_SUFFIX}"))
    assert torn_writes >= 1  # at least one kill landed mid-write (each write is most of the loop)


# --------------------------------------------------------------------------- the command line
def test_cli_simulate_prints_a_summary_and_saves_parquet(tmp_path, capsys):
    out = tmp_path / "tip.parquet"
    assert main(["simulate", "STUDY-R3", "--t-end", "0.2", "--sample", "0.05", "--out",
                 str(out)]) == 0
    text = capsys.readouterr().out
    assert "STUDY-R3 redysim/rge-a ode45 rtol=0.0001" in text and "E(0)" in text
    assert "|delta_M|     average" in text and "tip x [m]" in text
    samples = read_parquet(out)
    summary = read_parquet(tmp_path / "tip.summary.parquet")
    assert len(samples) == 5 and summary["status"].tolist() == ["ok"]
    table = text.split("COM z [m]")[1].split("saved:")[0]
    assert len(table.strip().splitlines()) == 5


def test_cli_exit_codes_for_bad_input_and_failed_runs(capsys):
    assert main(["simulate", "NO-SUCH-CASE"]) == 2
    assert capsys.readouterr().err.startswith("redysim: error: no case named 'NO-SUCH-CASE'")
    assert main(["simulate", "STUDY-R3", "--integrator", "rk4"]) == 2
    assert capsys.readouterr().err.startswith("redysim: error: command line: --h: missing: "
                                              "integrator 'rk4' is fixed-step")
    for bad in ("-1", "0", "nan", "inf"):
        with pytest.raises(SystemExit) as info:
            main(["simulate", "STUDY-R3", "--rtol", bad])
        assert info.value.code == 2
        assert f"argument --rtol: '{bad}' must be a finite number > 0" in capsys.readouterr().err
    # an engine's own integrator asked of the core: bad input, refused before anything runs
    assert main(["simulate", "STUDY-R3", "--integrator", "native", "--h", "0.01"]) == 2
    assert capsys.readouterr().err.startswith("redysim: error: command line: --integrator = "
                                              "'native': needs a reference engine")
    bad = Path(__file__).parent / "bad_inputs" / "states.toml"  # a state list, not a case
    assert main(["simulate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"redysim: error: {bad}: <top>.state = ") and "unknown field" in err
    assert len(err) < 600, "a long value is abbreviated, not dumped"


@pytest.mark.parametrize("argv, flag, fragment", [
    (["--rtol", "2"], "--rtol", "must be < 1"),
    (["--rtol", "1e-300", "--atol", "1e-300"], "--rtol", "must be at least"),
    (["--h", "1e-3"], "--h", "is the step of a fixed-step integrator"),
    (["--integrator", "rk4", "--h", "1e-9"], "--h", "steps over t_end"),
    (["--integrator", "rk4", "--h", "1e-3", "--rtol", "1e-6"], "--rtol", "adaptive"),
    (["--sample", "1e-9"], "--sample", "samples over t_end"),
    (["--t-end", "1e300"], "--t-end", "at most 1e+06 s"),
    (["--out", "x.txt"], "--out", "must end in .parquet or .csv"),
    (["--out", "no-such-folder/x.parquet"], "--out", "does not exist"),
])
def test_cli_refuses_settings_that_cannot_run_naming_the_flag(argv, flag, fragment, capsys,
                                                                monkeypatch, tmp_path):
    """Settings that hung (--sample 1e-9, rk4 at --h 1e-9, rtol 1e-300), were silently taken
    another way (--h with ode45, --rtol 2, --t-end 0, --out x.csv written as Parquet) or lost the
    run's result (--out in a missing folder) are refused before the run, naming the flag."""
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "STUDY-R3", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"redysim: error: command line: {flag}"), err
    assert fragment in err, err


def test_cli_zero_horizon_and_an_out_folder_are_refused(capsys, tmp_path):
    with pytest.raises(SystemExit):
        main(["simulate", "STUDY-R3", "--t-end", "0"])  # it silently ran the case's horizon
    assert "argument --t-end: '0' must be a finite number > 0" in capsys.readouterr().err
    assert main(["simulate", "STUDY-R3", "--t-end", "0.01", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "command line: --out" in err and "is a folder" in err  # the run finished, unsaved
    (tmp_path / "afile").write_text("x")  # a third battery: "its folder does not exist"
    assert main(["simulate", "STUDY-R3", "--t-end", "0.01", "--out",
                 str(tmp_path / "afile" / "x.parquet")]) == 2
    assert f"{str(tmp_path / 'afile')!r} is a file, not a folder" in capsys.readouterr().err


def test_cli_saves_csv_by_its_suffix(tmp_path, capsys):
    out = tmp_path / "tip.csv"
    assert main(["simulate", "STUDY-R3", "--t-end", "0.1", "--sample", "0.05", "--out",
                 str(out)]) == 0
    samples = pd.read_csv(out)
    assert list(samples.columns[:2]) == ["run_id", "t"] and len(samples) == 3
    assert pd.read_csv(tmp_path / "tip.summary.csv")["status"].tolist() == ["ok"]
    assert out.stat().st_mode & 0o777 == FILE_MODE  # the umask's mode, not mkstemp's 0600


def test_cli_max_wall_stops_a_long_run_and_keeps_its_samples(capsys):
    """A run that would take minutes (rk4 at a tiny step) stops at --max-wall with the samples
    it finished, and says so: stopped (exit code 3), by the user's wall-clock limit, not a
    failed result; progress lines go to stderr."""
    code = main(["simulate", "RE-U125-L1", "--integrator", "rk4", "--h", "1e-6", "--t-end",
                 "1", "--sample", "1e-4", "--max-wall", "2"])
    assert code == 3
    out, err = capsys.readouterr()
    assert "run stopped: stopped by the wall-clock limit, max_wall_s = 2 s" in err
    assert "status        stopped" in out and "0.0001" in out


def test_cli_max_cpu_fails_a_long_run_as_its_result(capsys):
    code = main(["simulate", "RE-U125-L1", "--integrator", "rk4", "--h", "1e-6", "--t-end",
                 "1", "--sample", "1e-4", "--max-cpu", "0.5"])
    assert code == 1
    out, err = capsys.readouterr()
    assert "run failed: time limit: max_cpu_s = 0.5 s of CPU reached" in err
    assert "status        failed" in out


def test_cli_output_into_a_closed_pipe_ends_quietly():
    """`redysim cases | head -1` and `redysim simulate ... | head`: no BrokenPipeError
    traceback."""
    for args in (["cases"], ["simulate", "STUDY-R3", "--t-end", "0.5", "--sample", "0.001"]):
        proc = subprocess.run(f"{shlex.quote(PYTHON)} -m redysim.harness.cli "
                              f"{' '.join(args)} | head -1", shell=True, cwd=REPO,
                              env=subprocess_env(), capture_output=True, text=True, timeout=120)
        assert proc.stdout.count("\n") == 1
        assert "Traceback" not in proc.stderr and "BrokenPipe" not in proc.stderr, proc.stderr


def test_cli_cases_lists_the_others_when_one_file_is_malformed(tmp_path):
    for name in ("STUDY-R3", "STUDY-R5"):
        (tmp_path / f"{name}.toml").write_text((REPO / "cases" / f"{name}.toml").read_text())
    (tmp_path / "BROKEN.toml").write_text("[case]\nname = \n")
    proc = subprocess.run([PYTHON, "-m", "redysim.harness.cli", "cases"], cwd=REPO,
                          env={**subprocess_env(), "REDYSIM_CASES": str(tmp_path)},
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("BROKEN") and "does not load" in lines[0] and "line 2" in lines[0]
    assert lines[1].startswith("STUDY-R3") and lines[2].startswith("STUDY-R5")
    assert "1 case file in" in proc.stderr


def test_cli_help_and_cases(capsys):
    for argv in (["--help"], ["simulate", "--help"], ["sweep", "--help"], ["cases", "--help"]):
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == 0
        assert "example" in capsys.readouterr().out
    assert main(["cases"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert any(line.startswith("RE-U125-L1 ") and "250 DOF" in line for line in lines)


def test_cli_import_does_not_import_pandas():
    code = "import sys, redysim.harness.cli; assert 'pandas' not in sys.modules, 'pandas imported'"
    subprocess.run([PYTHON, "-c", code], cwd=REPO, env=subprocess_env(), check=True, timeout=60)


# --------------------------------------------------------------------------- (d) sharing, death
def _sweep_cmd(path: Path, out: Path, *extra: str) -> list[str]:
    return [PYTHON, "-m", "redysim.harness.cli", "sweep", str(path), "--out", str(out),
            "--no-progress", *extra]


def _session_processes(sid: int) -> list:
    import psutil
    out = []
    for p in psutil.process_iter(["pid"]):
        try:
            if os.getsid(p.info["pid"]) == sid:
                out.append(p)
        except (ProcessLookupError, PermissionError):
            pass
    return out


@pytest.mark.slow
def test_killing_the_sweep_ends_its_pool_workers(tmp_path):
    """kill -9 of the sweep process alone (not its group): its pool workers notice within
    seconds and exit, and so does multiprocessing's resource tracker (they stayed, ~265 MB
    each, for ever)."""
    path = write(tmp_path, """
        [sweep]
        name = "orphans"
        cases = ["RE-U125-L1"]
        rtols = [1e-7, 2e-7, 3e-7, 4e-7]
        t_end = 0.5
        """)
    proc = subprocess.Popen(_sweep_cmd(path, tmp_path / "out", "--workers", "2"), cwd=REPO,
                            env=subprocess_env(), start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while len(_session_processes(proc.pid)) < 3:  # the sweep and its two workers
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.05)
    time.sleep(1.0)  # the workers are computing
    proc.kill()
    proc.wait(timeout=10)
    deadline = time.monotonic() + 20
    while (left := _session_processes(proc.pid)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not left, [p.cmdline() for p in left]


@pytest.mark.slow
def test_two_sweeps_on_one_folder_share_the_runs(tmp_path):
    """Two sweeps started together on the same file and folder: each run is computed once (each
    computed every pending run before), and both end with the whole table."""
    rtols = ", ".join(f"{k}e-7" for k in range(1, 9))
    path = write(tmp_path, f"""
        [sweep]
        name = "shared"
        cases = ["RE-U125-L1"]
        rtols = [{rtols}]
        t_end = 0.05
        """)
    out = tmp_path / "out"
    procs = [subprocess.Popen(_sweep_cmd(path, out, "--workers", "1"), cwd=REPO,
                              env=subprocess_env(), stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outputs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], outputs
    ran = [int(o.split(" run by this sweep")[0].rsplit(", ", 1)[1]) for o, _ in outputs]
    assert sum(ran) == 8 and min(ran) >= 1, outputs
    runs = read_parquet(out / RUNS_FILE)
    assert len(runs) == 8 and (runs["status"] == "ok").all()
    assert not list((out / CLAIMS_DIR).iterdir())


def test_a_claim_is_held_by_one_process_and_freed_by_its_death(tmp_path):
    claims = Claims(tmp_path)
    assert claims.take("abc")
    code = ("import sys; from pathlib import Path; from redysim.harness.sweep import Claims; "
            "c = Claims(Path(sys.argv[1])); print(c.take('abc'), c.take('xyz'))")
    other = subprocess.run([PYTHON, "-c", code, str(tmp_path)], capture_output=True, text=True,
                           env=subprocess_env(), check=True, timeout=60)
    assert other.stdout.split() == ["False", "True"]  # xyz freed when that process ended
    claims.release("abc")
    assert not (tmp_path / CLAIMS_DIR / "abc").exists()
    other = subprocess.run([PYTHON, "-c", code, str(tmp_path)], capture_output=True, text=True,
                           env=subprocess_env(), check=True, timeout=60)
    assert other.stdout.split() == ["True", "True"]


def test_which_failed_runs_a_resumed_sweep_runs_again(tmp_path):
    """A run whose worker died or raised is run again on resume (transient); a run that failed
    by itself is a result and is not, unless retry_failed."""
    out = tmp_path / "out"
    spec = RunSpec(case="STUDY-R3", t_end=0.05, sample=0.05)
    blowup = RunSpec(case="STUDY-R3", t_end=0.05, sample=0.05, energy_bound=1e-300)
    first = run_sweep([spec, blowup], out, progress=False)
    assert first.attrs["ran"] == 2
    assert first.set_index("run_id").loc[blowup.run_id, "status"] == "failed"
    assert not first["transient"].any()
    # the worker of `spec` "died": a transient failed row in its place
    write_parquet_atomic(pd.DataFrame([failed_row(spec, DIED)]),
                         out / RUNS_DIR / f"{spec.run_id}.parquet")
    again = run_sweep([spec, blowup], out, progress=False)
    assert again.attrs["ran"] == 1
    assert again.set_index("run_id")["status"].to_dict() == {spec.run_id: "ok",
                                                             blowup.run_id: "failed"}
    assert run_sweep([spec, blowup], out, progress=False).attrs["ran"] == 0
    retried = run_sweep([spec, blowup], out, progress=False, retry_failed=True)
    assert retried.attrs["ran"] == 1


@pytest.mark.parametrize("damage", ["empty", "garbage", "truncated"])
@pytest.mark.parametrize("which", [RUNS_DIR, SAMPLES_DIR])
def test_a_damaged_result_file_is_set_aside_and_its_run_done_again(tmp_path, damage, which,
                                                                    capsys):
    out = tmp_path / "out"
    specs = TINY[:2]
    run_sweep(specs, out, progress=False)
    victim = out / which / f"{specs[0].run_id}.parquet"
    data = victim.read_bytes()
    victim.write_bytes({"empty": b"", "garbage": os.urandom(300),
                        "truncated": data[:len(data) // 2]}[damage])
    runs = run_sweep(specs, out, progress=False)  # ArrowInvalid blocked every resume before
    assert runs.attrs["ran"] == 1 and len(runs) == 2 and (runs["status"] == "ok").all()
    err = capsys.readouterr().err
    assert f"{victim} could not be read" in err and "done again" in err
    assert list((out / DAMAGED_DIR).iterdir())
    assert len(read_parquet(out / SAMPLES_FILE)["run_id"].unique()) == 2


def test_sweep_inputs_that_crashed_now_fail_with_a_named_error(tmp_path, capsys, monkeypatch):
    random_bytes = tmp_path / "random.toml"
    random_bytes.write_bytes(bytes(range(256)) * 4)
    assert main(["sweep", str(random_bytes)]) == 2
    assert "<toml syntax>" in capsys.readouterr().err
    good = write(tmp_path, '[sweep]\ncases = ["STUDY-R3"]\nt_end = 0.05\n')
    a_file = tmp_path / "results-file"
    a_file.write_text("x")
    assert main(["sweep", str(good), "--out", str(a_file)]) == 2
    assert "--out" in capsys.readouterr().err
    monkeypatch.setattr("redysim.harness.sweep.DASK_CONNECT_TIMEOUT_S", 1)
    t0 = time.monotonic()
    assert main(["sweep", str(good), "--out", str(tmp_path / "o"), "--dask",
                 "tcp://127.0.0.1:9"]) == 2
    assert time.monotonic() - t0 < 20
    assert "no Dask scheduler answered" in capsys.readouterr().err


# --------------------------------------------------------------------------- (e) what is kept
def _mtimes(folder: Path) -> dict:
    return {p.relative_to(folder): p.stat().st_mtime_ns for p in folder.rglob("*")
            if p.is_file()}


def test_a_finished_runs_deleted_samples_file_is_said_and_its_run_done_again(tmp_path, capsys):
    """A finished run whose samples file was deleted: the sweep said nothing, counted it done,
    and its samples.parquet lacked the run."""
    out = tmp_path / "out"
    specs = TINY[:2]
    run_sweep(specs, out, progress=False)
    victim = out / SAMPLES_DIR / f"{specs[1].run_id}.parquet"
    victim.unlink()
    runs = run_sweep(specs, out, progress=False)
    assert runs.attrs["ran"] == 1 and (runs["status"] == "ok").all()
    assert f"{victim} is missing" in capsys.readouterr().err
    assert read_parquet(out / SAMPLES_FILE)["run_id"].nunique() == 2  # (it held 1)
    assert run_sweep(specs, out, progress=False).attrs["ran"] == 0


def test_a_result_file_replaced_by_another_readable_one_is_caught_by_its_digest(tmp_path,
                                                                                 capsys):
    """A samples file swapped for another run's (valid Parquet, so readable): the manifest's
    SHA-256 tells, the file is set aside and the run done again."""
    out = tmp_path / "out"
    specs = TINY[:2]
    run_sweep(specs, out, progress=False)
    a, b = (out / SAMPLES_DIR / f"{s.run_id}.parquet" for s in specs)
    a.write_bytes(b.read_bytes())
    runs = run_sweep(specs, out, progress=False)
    assert runs.attrs["ran"] == 1
    assert "SHA-256" in capsys.readouterr().err and list((out / DAMAGED_DIR).iterdir())
    table = read_parquet(out / SAMPLES_FILE)
    assert table["run_id"].nunique() == 2
    assert sorted(table.groupby("run_id").size()) == sorted(runs["n_samples"])


@pytest.mark.parametrize("damage", ["manifest deleted", "manifest damaged", "run deleted",
                                    "manifest lists nothing", "another run's manifest",
                                    "a folder for the run", "a folder for its samples"])
def test_a_run_whose_record_is_gone_is_said_and_done_again(tmp_path, capsys, damage):
    """A hold-out battery: a finished run's summary row changed and its manifest deleted (or
    made unreadable) was taken as finished, the changed row kept ("0 run by this sweep"; a
    damaged manifest was even said to be redone); a deleted summary row was redone without a
    word. A second battery: a manifest listing no files, or another run's, let a changed row
    through; a folder in the row's place was a traceback. A sweep writes a run's manifest
    before its summary row, so a row without its own manifest, listing it, is not a finished
    run's: each is said and its run done again, the changed value gone."""
    out = tmp_path / "out"
    specs = TINY[:2]
    run_sweep(specs, out, progress=False)
    row = out / RUNS_DIR / f"{specs[1].run_id}.parquet"
    manifest = out / "manifest" / f"{specs[1].run_id}.json"
    table = read_parquet(row)
    table["steps"] = 999999
    table.to_parquet(row, index=False)
    if damage == "manifest deleted":
        manifest.unlink()
    elif damage == "manifest damaged":
        manifest.write_text('{"bad": 1')
    elif damage == "manifest lists nothing":
        manifest.write_text(json.dumps({"run_id": specs[1].run_id, "files": {}}))
    elif damage == "another run's manifest":
        manifest.write_bytes((out / "manifest" / f"{specs[0].run_id}.json").read_bytes())
    elif damage == "a folder for the run":
        row.unlink()
        row.mkdir()
    elif damage == "a folder for its samples":  # (a third battery: said to be "missing")
        samples = out / SAMPLES_DIR / f"{specs[1].run_id}.parquet"
        samples.unlink()
        samples.mkdir()
    else:
        row.unlink()
    runs = run_sweep(specs, out, progress=False)
    assert runs.attrs["ran"] == 1 and (runs["status"] == "ok").all()
    err = capsys.readouterr().err
    assert ("is missing" in err or "could not be read" in err) and specs[1].run_id in err
    assert (read_parquet(out / RUNS_FILE)["steps"] != 999999).all()
    assert run_sweep(specs, out, progress=False).attrs["ran"] == 0


@pytest.mark.parametrize("forgery", ["run B's row under A's name", "rtol edited",
                                     "integrator edited"])
def test_a_row_that_is_not_its_runs_is_set_aside_even_with_its_digest_recomputed(
        tmp_path, capsys, forgery):
    """A third hold-out battery: a finished run's summary row replaced by another run's (or
    its plan fields, rtol or integrator, edited), its manifest's SHA-256 recomputed to match,
    was taken as finished: runs.parquet held run B twice and run A nowhere. A row records its
    run's id and settings; the sweep compares them with the run it stands for."""
    out = tmp_path / "out"
    specs = [TINY[3], TINY[0]]
    run_sweep(specs, out, progress=False)
    a, b = (out / RUNS_DIR / f"{s.run_id}.parquet" for s in specs)
    if forgery == "run B's row under A's name":
        a.write_bytes(b.read_bytes())
    else:
        table = read_parquet(a)
        if forgery == "rtol edited":
            table["rtol"] = 1e-3
        else:
            table["integrator"] = "rk4"
        table.to_parquet(a, index=False)
    manifest = out / "manifest" / f"{specs[0].run_id}.json"
    record = json.loads(manifest.read_text())
    record["files"][a.relative_to(out).as_posix()] = hashlib.sha256(a.read_bytes()).hexdigest()
    manifest.write_text(json.dumps(record))
    runs = run_sweep(specs, out, progress=False)
    assert runs.attrs["ran"] == 1
    assert specs[0].run_id in capsys.readouterr().err
    table = read_parquet(out / RUNS_FILE)
    assert sorted(table["run_id"]) == sorted(s.run_id for s in specs)
    first = table[table["run_id"] == specs[0].run_id].iloc[0]
    assert (first["rtol"], first["integrator"]) == (specs[0].rtol, specs[0].integrator)
    assert run_sweep(specs, out, progress=False).attrs["ran"] == 0


@pytest.mark.parametrize("sub", [SAMPLES_DIR, RUNS_DIR, "manifest"])
def test_a_results_subfolder_replaced_by_a_file_is_refused_by_name(tmp_path, sub):
    """A third hold-out battery: `rm -r OUT/samples; echo x > OUT/samples` then the sweep again
    was a FileExistsError traceback from the folder's mkdir."""
    out = tmp_path / "out"
    run_sweep(TINY[:1], out, progress=False)
    shutil.rmtree(out / sub)
    (out / sub).write_text("x")
    with pytest.raises(SweepError, match=f"{sub}.*is a file where the sweep keeps"):
        run_sweep(TINY[:1], out, progress=False)
    assert (out / sub).read_text() == "x"


def test_a_finished_sweep_run_again_rewrites_nothing(tmp_path):
    out = tmp_path / "out"
    run_sweep(TINY[:2], out, progress=False)
    before = _mtimes(out)
    assert run_sweep(TINY[:2], out, progress=False).attrs["ran"] == 0
    assert _mtimes(out) == before


def _as_a_user_who_cannot_write(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """The redysim command in a process that file permissions bind: root's overriding of them
    (CAP_DAC_OVERRIDE) dropped, so that a folder without write permission is one."""
    cmd = [PYTHON, "-m", "redysim.reports.commands", *argv]
    if os.geteuid() == 0:
        cmd = ["setpriv", "--bounding-set=-dac_override,-dac_read_search,-fowner", *cmd]
    return subprocess.run(cmd, cwd=cwd, env=subprocess_env(), capture_output=True, text=True,
                          timeout=300)


def _read_only(folder: Path) -> None:
    for p in [folder, *folder.rglob("*")]:
        p.chmod(0o555 if p.is_dir() else 0o444)


@pytest.mark.skipif(os.geteuid() == 0 and not shutil.which("setpriv"),
                    reason="as root, a read-only file needs setpriv to drop the override")
def test_simulate_keeps_a_read_only_out_file(tmp_path):
    """A hold-out battery: simulate --out onto a read-only file in a writable folder replaced it
    (an atomic rename ignores the file's own mode). Now refused by name before the run, the file
    kept."""
    target = tmp_path / "f.csv"
    target.write_text("keep\n")
    target.chmod(0o444)
    res = _as_a_user_who_cannot_write(
        ["simulate", "STUDY-R3", "--t-end", "0.02", "--out", str(target)], tmp_path)
    assert res.returncode == 2, (res.stdout, res.stderr)
    assert "may not be written" in res.stderr and str(target) in res.stderr
    assert target.read_text() == "keep\n" and not (tmp_path / "f.summary.csv").exists()


@pytest.mark.skipif(os.geteuid() == 0 and not shutil.which("setpriv"),
                    reason="as root, a read-only folder needs setpriv to drop the override")
def test_a_folder_that_cannot_be_written_is_refused_by_name_before_any_run(tmp_path):
    """simulate --out, sweep, longrun and compare into a read-only folder printed a traceback
    (PermissionError from the atomic writer); a finished sweep there was read, but sweep.json
    rewritten. Now: each refused, naming the folder, why and what to do, before any run; the
    finished sweep read as it is, nothing written."""
    path = write(tmp_path, """
        [sweep]
        name = "ro"
        cases = ["STUDY-R3"]
        t_end = 0.05
        sample = 0.05
        """)
    done = tmp_path / "done"
    assert main(["sweep", str(path), "--out", str(done), "--no-progress"]) == 0
    ro = tmp_path / "ro"
    ro.mkdir()
    _read_only(ro)
    _read_only(done)
    before = _mtimes(done)
    try:
        for argv in (["sweep", str(path), "--out", str(ro), "--no-progress"],
                     ["simulate", "STUDY-R3", "--t-end", "0.05", "--out", str(ro / "s.parquet")],
                     ["compare", "STUDY-R3", "--out", str(ro / "cmp"), "--no-progress"]):
            res = _as_a_user_who_cannot_write(argv, tmp_path)
            assert res.returncode == 2, (argv, res.stderr)
            assert "Traceback" not in res.stderr and "cannot be written" in res.stderr
            assert str(ro) in res.stderr and "--out" in res.stderr, res.stderr
        res = subprocess.run(
            ["setpriv", "--bounding-set=-dac_override,-dac_read_search,-fowner"]
            * (os.geteuid() == 0) + [PYTHON, "-m", "redysim.harness.longrun", "STUDY-R3",
                                     "--t-end", "0.05", "--out", str(ro / "long")],
            cwd=tmp_path, env=subprocess_env(), capture_output=True, text=True, timeout=300)
        assert res.returncode == 2 and "Traceback" not in res.stderr
        assert str(ro / "long") in res.stderr and "cannot be written" in res.stderr
        assert not list(ro.iterdir())
        res = _as_a_user_who_cannot_write(["sweep", str(path), "--out", str(done),
                                           "--no-progress"], tmp_path)
        assert res.returncode == 0, res.stderr
        assert "1 ok, 0 failed, 0 run by this sweep" in res.stdout
        assert _mtimes(done) == before
    finally:
        for folder in (ro, done):
            for p in [folder, *folder.rglob("*")]:
                p.chmod(0o755 if p.is_dir() else 0o644)
