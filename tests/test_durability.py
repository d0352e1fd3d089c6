"""Durability: a failing, refusing or missing engine never takes the process down, and results on
disk are never torn.

harness.run.execute must return a failed row with its reason (never raise) for: an engine that
refuses the case (limits), an engine whose package does not import (monkeypatched), and an engine
that raises, returns NaN or returns the wrong shape inside qdd, at the first call or mid-run
(the samples before the failure are kept). The atomic writers of harness.store leave the old
file and no temporary file when the serialisation itself fails; the gates' --json is written
through them.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
import types

import numpy as np
import pandas as pd
import pytest

from redysim import load_case, references
from redysim.harness import gates
from redysim.harness.reference import compute_reference, reference_path
from redysim.harness.run import execute
from redysim.harness.spec import RunSpec
from redysim.harness.store import (
    TEMP_PREFIX,
    TEMP_SUFFIX,
    read_json,
    read_parquet,
    remove_temp_files,
    write_json_atomic,
    write_parquet_atomic,
)

SHORT = dict(t_end=0.2, sample=0.05)  # STUDY-R3, 4 samples after t = 0
FAIL_AFTER_CALLS = 40  # a mid-run failure: after the first samples are taken


@pytest.fixture(autouse=True)
def results_in_tmp(tmp_path, monkeypatch):
    """Reference solutions go to a temporary results directory."""
    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path / "results"))


# --------------------------------------------------------------------------- a misbehaving engine
class Misbehaving(references.Engine):
    """An engine adapter whose qdd misbehaves in the way ``mode`` says; qdd = -q (a stable linear
    system) until it does."""

    name = "misbehaving"
    package = "numpy"  # importable everywhere
    module = "numpy"
    integrator = "none"
    mode = "raise"
    after = 0  # misbehave from this call on

    @classmethod
    def limits(cls, case_or_chain):
        return references.Limits(True)

    def _build(self):
        if self.mode == "build":
            raise RuntimeError("model build failed")
        self.calls = 0

    def _qdd(self, q, qd, tau):
        self.calls += 1
        if self.calls <= self.after:
            return -q
        if self.mode == "raise":
            raise RuntimeError("solver exploded")
        if self.mode == "memory":
            raise MemoryError("cannot allocate the mass matrix")
        if self.mode == "fpe":
            raise FloatingPointError("overflow in the factorisation")
        if self.mode == "nan":
            return np.full(q.shape, np.nan)
        if self.mode == "shape":
            return np.zeros(q.size + 1)
        raise AssertionError(self.mode)


def misbehaving(monkeypatch, mode, after=0):
    cls = type(f"Misbehaving_{mode}", (Misbehaving,), {"mode": mode, "after": after})
    monkeypatch.setitem(references.ENGINES, Misbehaving.name, cls)
    return cls


@pytest.mark.parametrize("mode, after, reason", [
    ("raise", 0, "RuntimeError: solver exploded (at test_durability.py:"),
    ("raise", FAIL_AFTER_CALLS, "RuntimeError: solver exploded"),
    ("memory", 0, "MemoryError: cannot allocate the mass matrix"),
    ("fpe", FAIL_AFTER_CALLS, "FloatingPointError: overflow in the factorisation"),
    ("nan", 0, "StateError: qdd[0] = nan: not finite"),
    ("nan", FAIL_AFTER_CALLS, "non-finite error estimate"),
    ("shape", 0, "StateError: run STUDY-R3 misbehaving ode45 rtol=0.0001: the accelerations' "
              "provider (qdd) returned shape (4,)"),
    ("build", 0, "RuntimeError: model build failed"),
])
def test_an_engine_failing_inside_qdd_gives_a_failed_row(monkeypatch, mode, after, reason):
    misbehaving(monkeypatch, mode, after)
    res = execute(RunSpec(case="STUDY-R3", engine=Misbehaving.name, **SHORT))
    assert res.summary["status"] == "failed"
    assert reason in res.summary["reason"], res.summary["reason"]
    if after:  # a mid-run failure keeps the samples taken before it
        assert 1 <= res.summary["n_samples"] < 5
        assert np.isfinite(res.samples["E"]).all()
    else:
        assert res.summary["n_samples"] == 0


@pytest.mark.parametrize("integrator, h", [("dop853", 0.0), ("rk4", 1e-3),
                                           ("scipy-RK45", 0.0)])
def test_a_mid_run_nan_fails_every_integrator_without_hanging(monkeypatch, integrator, h):
    misbehaving(monkeypatch, "nan", FAIL_AFTER_CALLS)
    res = execute(RunSpec(case="STUDY-R3", engine=Misbehaving.name, integrator=integrator, h=h,
                          max_cpu_s=60.0, **SHORT))
    assert res.summary["status"] == "failed"
    assert "time limit" not in res.summary["reason"]
    assert "nan" in res.summary["reason"] or "non-finite" in res.summary["reason"]


def test_an_engine_that_refuses_the_case_gives_a_failed_row_before_building(monkeypatch):
    """RE-U375-L3 has 750 DOF, above Pinocchio's measured 700 (references/limits.toml)."""
    def no_import(*_args, **_kw):
        raise AssertionError("a refused case must not import or build the engine")

    monkeypatch.setattr(references.base, "import_engine", no_import)
    res = execute(RunSpec(case="RE-U375-L3", engine="pinocchio-crba", t_end=0.01))
    assert res.summary["status"] == "failed"
    assert res.summary["reason"].startswith("refused by the engine: pinocchio-crba: 750 DOF "
                                            "exceeds its limit")


def test_an_engine_refuses_a_chain_beyond_its_limit_before_building_it():
    """MuJoCo's compiler refuses a body tree deeper than 1,023: RE-U1250-L10's run fails at
    once with that reason (every engine now builds every joint type, so it is the size that is
    refused)."""
    t0 = time.perf_counter()
    res = execute(RunSpec(case="RE-U1250-L10", engine="mujoco", t_end=0.01))
    assert time.perf_counter() - t0 < 30  # refused before a 10 s compile, not after
    assert res.summary["status"] == "failed"
    assert res.summary["reason"].startswith("refused by the engine: mujoco: 2,500 DOF exceeds")
    assert "depth" in res.summary["reason"]


@pytest.mark.parametrize("error", [ImportError("No module named 'mujoco'"),
                                   OSError("libmujoco.so: undefined symbol: mj_step")])
def test_an_engine_whose_package_does_not_import_gives_a_failed_row(monkeypatch, error):
    real = references.base.importlib.import_module

    def import_module(name, *args):
        if name.split(".")[0] == "mujoco":
            raise error
        return real(name, *args)

    monkeypatch.setattr(references.base, "importlib",
                        types.SimpleNamespace(import_module=import_module))
    res = execute(RunSpec(case="STUDY-R3", engine="mujoco", **SHORT))
    assert res.summary["status"] == "failed"
    reason = res.summary["reason"]
    assert reason.startswith("EngineUnavailable: engine 'mujoco' needs the Python package "
                             "'mujoco', which is not installed or does not import"), reason
    assert type(error).__name__ in reason and str(error) in reason


def test_an_unknown_engine_gives_a_failed_row():
    res = execute(RunSpec(case="STUDY-R3", engine="no-such-engine", **SHORT))
    assert res.summary["status"] == "failed"
    assert "no engine 'no-such-engine'; known engines:" in res.summary["reason"]


def test_a_corrupt_cached_reference_does_not_take_execute_down():
    case = load_case("STUDY-R3")
    compute_reference(case, SHORT["t_end"], SHORT["sample"])
    reference_path(case, SHORT["t_end"], SHORT["sample"]).write_bytes(b"not an npz file")
    res = execute(RunSpec(case="STUDY-R3", **SHORT))
    assert res.summary["status"] == "ok"
    assert math.isnan(res.summary["max_tip_err"])  # read as missing, not as a reference
    assert compute_reference(case, SHORT["t_end"], SHORT["sample"]).tol_estimate >= 0


# --------------------------------------------------------------------------- atomic writes
def _temp_files(directory):
    return sorted(directory.glob(f"{TEMP_PREFIX}*{TEMP_SUFFIX}"))


def test_a_parquet_writer_that_fails_mid_write_keeps_the_old_file(tmp_path):
    path = tmp_path / "runs.parquet"
    old = pd.DataFrame({"run_id": ["a", "b"], "value": [1.0, 2.0]})
    write_parquet_atomic(old, path)
    bad = pd.DataFrame({"run_id": ["c"], "value": [object()]})  # pyarrow cannot store it
    with pytest.raises(Exception):  # noqa: B017 - pyarrow's own error type
        write_parquet_atomic(bad, path)
    pd.testing.assert_frame_equal(read_parquet(path), old)
    assert _temp_files(tmp_path) == []


def test_a_json_writer_that_fails_keeps_the_old_file(tmp_path):
    path = tmp_path / "gates.json"
    write_json_atomic({"rows": [1, 2]}, path)
    with pytest.raises(TypeError):
        write_json_atomic({"rows": [object()]}, path)
    assert read_json(path) == {"rows": [1, 2]}
    assert _temp_files(tmp_path) == []


def test_a_writer_interrupted_inside_the_write_leaves_no_temp_file(tmp_path, monkeypatch):
    """KeyboardInterrupt (or any BaseException) during the write: old file kept, temp removed."""
    path = tmp_path / "runs.parquet"
    old = pd.DataFrame({"x": [1, 2, 3]})
    write_parquet_atomic(old, path)

    def interrupted(self, fh, **_kw):
        fh.write(b"PAR1 partial")
        raise KeyboardInterrupt

    monkeypatch.setattr(pd.DataFrame, "to_parquet", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_parquet_atomic(pd.DataFrame({"x": [9]}), path)
    monkeypatch.undo()
    pd.testing.assert_frame_equal(read_parquet(path), old)
    assert _temp_files(tmp_path) == []


def test_the_gates_json_is_written_atomically_and_is_valid_json(tmp_path, monkeypatch):
    out = tmp_path / "gates.json"
    calls = []
    real = write_json_atomic

    def spy(obj, path):
        calls.append(path)
        return real(obj, path)

    monkeypatch.setattr("redysim.harness.store.write_json_atomic", spy)
    assert gates.main(["--only", "table9.cond2", "--json", str(out)]) == gates.EXIT_OK
    assert calls == [str(out)]
    doc = json.loads(out.read_text())  # strict JSON: no NaN
    assert [r["gate"] for r in doc["rows"]] == ["table9.cond2"]
    assert doc["rows"][0]["result"] == gates.PASS


def test_an_edited_kernel_source_drops_numbas_cache(tmp_path):
    """numba would load a kernel's stale machine code after an edit to a callee in another file;
    the cache is dropped whenever any kernel source changes
    (redysim/algorithms/_kernels/__init__.py)."""
    from redysim.algorithms import _kernels
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    (cache / "kinematics.kinematics-29.py311.nbi").write_bytes(b"old")
    (cache / "kinematics.kinematics-29.py311.1.nbc").write_bytes(b"old")
    (cache / _kernels.STAMP).write_text("digest of other sources")
    assert _kernels.drop_stale_cache(cache)
    assert not list(cache.glob("*.nb?"))
    assert (cache / _kernels.STAMP).read_text() == _kernels.sources_digest()
    (cache / "kinematics.kinematics-29.py311.nbi").write_bytes(b"current")
    assert not _kernels.drop_stale_cache(cache), "sources unchanged: the cache stays"
    assert (cache / "kinematics.kinematics-29.py311.nbi").exists()


def test_cleaning_up_leaves_a_live_writer_s_temporary_file(tmp_path):
    """A sweep starting on a folder where another sweep is writing removes only the temporary
    files of dead writers (it removed every one, and the other sweep's rename then failed)."""
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        live = tmp_path / f"{TEMP_PREFIX}run.parquet.{sleeper.pid}.abc{TEMP_SUFFIX}"
        dead = tmp_path / f"{TEMP_PREFIX}run.parquet.999999999.abc{TEMP_SUFFIX}"
        old = tmp_path / f"{TEMP_PREFIX}run.parquet.abc{TEMP_SUFFIX}"  # a name without a pid
        for p in (live, dead, old):
            p.write_bytes(b"x")
        assert remove_temp_files(tmp_path) == 2
        assert live.exists() and not dead.exists() and not old.exists()
    finally:
        sleeper.kill()
        sleeper.wait()
    assert remove_temp_files(tmp_path) == 1 and not live.exists()
