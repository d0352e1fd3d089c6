"""A long run killed with SIGKILL resumes from its checkpoint and ends bit for bit where an
uninterrupted run ends."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from redysim.harness.longrun import CHECKPOINT, load_checkpoint, run

# Long enough (about 2,200 steps) that a kill landing within a few milliseconds of the first
# checkpoint (written after 0.02 s of wall time) leaves most of the run undone even on a fast,
# idle machine: CI once finished a 0.2 s run in the 0.15 s the test used to wait.
CASE, T_END = "RE-U125-L1", 0.5


@pytest.mark.slow
def test_kill_9_then_resume_is_bit_identical(tmp_path):
    whole = run(CASE, t_end=T_END, every_s=1e9, out=tmp_path / "whole", log=lambda m: None)
    out = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "redysim.harness.longrun", CASE,
                             "--t-end", str(T_END), "--every", "0.02", "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})
    deadline = time.monotonic() + 120
    while not (out / CHECKPOINT).exists() and time.monotonic() < deadline:
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    partial = load_checkpoint(out / CHECKPOINT)
    print("killed at t =", float(partial["t"]) if partial is not None else None)
    assert partial is not None and 0 < float(partial["t"]) < T_END, "killed mid-run"
    resumed = run(CASE, t_end=T_END, every_s=0.02, out=out, log=lambda m: None)
    assert np.array_equal(resumed["y"], whole["y"])
    assert np.array_equal(resumed["samples"], whole["samples"])
    for key in ("steps", "rejected", "nfev"):
        assert int(resumed[key]) == int(whole[key])
    assert not list(out.glob(".*.tmp")), "no temporary files left behind"


def test_a_checkpoint_for_other_settings_is_not_silently_reused(tmp_path):
    run("STUDY-R3", t_end=0.1, every_s=1e9, out=tmp_path, log=lambda m: None)
    with pytest.raises(SystemExit, match="t_end = 0.1"):
        run("STUDY-R3", t_end=0.2, every_s=1e9, out=tmp_path, log=lambda m: None)


def test_a_checkpoint_written_by_other_code_is_not_resumed(tmp_path, monkeypatch):
    import redysim.harness.longrun as longrun
    run("STUDY-R3", t_end=0.1, every_s=1e9, out=tmp_path, log=lambda m: None)
    monkeypatch.setattr(longrun, "code_digest", lambda: "0" * 64)
    with pytest.raises(SystemExit, match="written by other code"):
        run("STUDY-R3", t_end=0.1, every_s=1e9, out=tmp_path, log=lambda m: None)
