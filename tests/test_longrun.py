"""A long run killed with SIGKILL resumes from its checkpoint and ends bit for bit where an
uninterrupted run ends."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from redysim.errors import SettingsError
from redysim.harness.longrun import (
    CHECKPOINT,
    PREVIOUS,
    LongrunError,
    load_checkpoint,
    main,
    run,
)
from redysim.io.cases import CASES_DIR

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


def quiet(_msg):
    return None


def test_a_checkpoint_for_other_settings_is_not_silently_reused(tmp_path):
    run("STUDY-R3", t_end=0.1, every_s=1e9, out=tmp_path, log=quiet)
    with pytest.raises(LongrunError, match="t_end = 0.1"):
        run("STUDY-R3", t_end=0.2, every_s=1e9, out=tmp_path, log=quiet)
    with pytest.raises(LongrunError, match="integrator = 'ode45'"):
        run("STUDY-R3", t_end=0.1, integrator="dop853", every_s=1e9, out=tmp_path, log=quiet)


def test_a_checkpoint_written_by_other_code_is_not_resumed(tmp_path, monkeypatch):
    import redysim.harness.longrun as longrun
    run("STUDY-R3", t_end=0.1, every_s=1e9, out=tmp_path, log=quiet)
    monkeypatch.setattr(longrun, "code_digest", lambda: "0" * 64)
    with pytest.raises(LongrunError, match="written by other code"):
        run("STUDY-R3", t_end=0.1, every_s=1e9, out=tmp_path, log=quiet)


def test_set_aside_keeps_the_other_codes_checkpoint_and_starts_over(tmp_path, monkeypatch):
    """With --set-aside (what make reproduce passes) a finished checkpoint of other code is
    renamed beside the new one, byte for byte, not resumed: the new run is a fresh run's."""
    import redysim.harness.longrun as longrun
    run("STUDY-R3", t_end=0.05, every_s=1e9, out=tmp_path / "fresh", log=quiet)
    fresh = load_checkpoint(tmp_path / "fresh" / CHECKPOINT)
    with monkeypatch.context() as m:
        m.setattr(longrun, "code_digest", lambda: "0" * 64)
        run("STUDY-R3", t_end=0.05, every_s=1e9, out=tmp_path, log=quiet)
    old = (tmp_path / CHECKPOINT).read_bytes()
    said = []
    assert main(["STUDY-R3", "--t-end", "0.05", "--out", str(tmp_path), "--set-aside"]) == 0
    new = run("STUDY-R3", t_end=0.05, every_s=1e9, out=tmp_path, log=said.append,
              set_aside=True)  # now its own: resumed (finished), nothing set aside
    aside = sorted(tmp_path.glob("checkpoint.aside-*.npz"))
    assert [p.read_bytes() for p in aside if ".prev" not in p.name] == [old]
    assert not any("set aside" in m for m in said)
    for key in ("y", "samples", "code"):
        assert np.array_equal(new[key], fresh[key])
    assert int(new["steps"]) == int(fresh["steps"])


@pytest.mark.parametrize("edit, what", [("density = 7025.0", "same DOF, other density"),
                                        ("links = 4", "another DOF")])
def test_a_checkpoint_of_a_case_with_the_same_name_is_not_resumed(tmp_path, edit, what):
    """Two case files named alike: the second neither continues the first's state with its own
    dynamics (same DOF) nor fails with a broadcast traceback (other DOF): both are named."""
    text = (CASES_DIR / "STUDY-R3.toml").read_text()
    first, second = tmp_path / "a.toml", tmp_path / "b.toml"
    first.write_text(text)
    second.write_text(text.replace("links = 3", edit) if "links" in edit
                      else text.replace("density = 7025", "density = 7800"))
    assert first.read_text() != second.read_text(), what
    out = tmp_path / "out"
    run(str(first), t_end=0.1, every_s=1e9, out=out, log=quiet)
    before = (out / CHECKPOINT).read_bytes()
    with pytest.raises(LongrunError) as err:
        run(str(second), t_end=0.1, every_s=1e9, out=out, log=quiet)
    msg = str(err.value)
    assert "the checkpoint was written for case 'STUDY-R3' (3 DOF" in msg
    assert "this is case 'STUDY-R3' (" in msg and "dynamics" in msg
    assert (out / CHECKPOINT).read_bytes() == before  # not overwritten


def test_the_case_s_integrator_and_tolerances_are_honoured(tmp_path):
    text = (CASES_DIR / "STUDY-R3.toml").read_text()
    case = tmp_path / "c.toml"
    case.write_text(text.replace('integrator = "ode45"', 'integrator = "dop853"')
                    .replace("rtol = 1e-4", "rtol = 1e-8").replace("atol = 1e-6", "atol = 1e-10"))
    ck = run(str(case), t_end=0.2, every_s=1e9, out=tmp_path / "o", log=quiet)
    assert (str(ck["integrator"]), float(ck["rtol"]), float(ck["atol"])) == ("dop853", 1e-8, 1e-10)
    fixed = tmp_path / "f.toml"
    fixed.write_text(text.replace('integrator = "ode45"', 'integrator = "rk4"\nh = 0.01')
                     .replace("rtol = 1e-4\n", "").replace("atol = 1e-6\n", ""))
    ck = run(str(fixed), t_end=0.2, every_s=1e9, out=tmp_path / "f", log=quiet)
    assert (str(ck["integrator"]), float(ck["fixed_h"]), int(ck["steps"])) == ("rk4", 0.01, 20)
    scipy = tmp_path / "s.toml"
    scipy.write_text(text.replace('integrator = "ode45"', 'integrator = "scipy-RK45"'))
    with pytest.raises(SettingsError, match="SciPy's state cannot be saved"):
        run(str(scipy), t_end=0.2, every_s=1e9, out=tmp_path / "s", log=quiet)


@pytest.mark.parametrize("damage", ["truncated", "garbage", "empty"])
def test_a_damaged_checkpoint_falls_back_to_the_previous_one(tmp_path, damage):
    """A truncated or corrupted checkpoint gave BadZipFile, EOFError or a pickle hint on resume
    and on --status: it is moved aside, said, and the previous checkpoint resumed instead."""
    out = tmp_path / "out"
    ck = run("STUDY-R3", t_end=0.3, every_s=0.0, stop_after_s=0.0, out=out, log=quiet)
    assert str(ck["status"]) == "stopped" and (out / PREVIOUS).exists()
    data = (out / CHECKPOINT).read_bytes()
    (out / CHECKPOINT).write_bytes({"truncated": data[:len(data) // 2], "empty": b"",
                                    "garbage": b"PK\x03\x04" + bytes(range(256))}[damage])
    said = []
    assert main(["STUDY-R3", "--out", str(out), "--status"]) == 0  # reads the previous one
    ck = run("STUDY-R3", t_end=0.3, every_s=1e9, out=out, log=said.append)
    assert str(ck["status"]) == "done" and float(ck["t"]) == 0.3
    assert any("could not be read" in m and "moved to" in m for m in said), said
    assert any(m.startswith("STUDY-R3: resuming at t = ") for m in said), said
    assert list(out.glob(f"{CHECKPOINT}.damaged-*"))
    whole = run("STUDY-R3", t_end=0.3, every_s=1e9, out=tmp_path / "whole", log=quiet)
    assert np.array_equal(ck["y"], whole["y"])  # the same end as an uninterrupted run


@pytest.mark.parametrize("argv, fragment", [
    (["STUDY-R3", "--t-end", "-1"], "must be a finite number > 0"),
    (["STUDY-R3", "--t-end", "nan"], "must be a finite number > 0"),
    (["STUDY-R3", "--t-end", "inf"], "must be a finite number > 0"),
    (["STUDY-R3", "--t-end", "0"], "must be a finite number > 0"),
    (["STUDY-R3", "--every", "0"], "must be a finite number > 0"),
])
def test_bad_arguments_exit_2_without_a_traceback(argv, fragment, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2 and fragment in capsys.readouterr().err


def test_a_missing_or_malformed_case_and_a_failed_run_exit_nonzero(tmp_path, capsys):
    assert main(["NO-SUCH-CASE", "--out", str(tmp_path)]) == 2
    assert "no case named 'NO-SUCH-CASE'" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text("[case]\nname = 3\n")
    assert main([str(bad), "--out", str(tmp_path)]) == 2
    assert "case.name = 3" in capsys.readouterr().err
    # a run that fails (rk4 far past its stability limit: the state overflows) exits 1, not 0
    assert main(["RE-U125-L1", "--integrator", "rk4", "--h", "0.01", "--t-end", "1", "--out",
                 str(tmp_path / "b")]) == 1
    out = capsys.readouterr().out  # the compiled steps see qdd go non-finite in a stage
    assert "FAILED: qdd not finite in a stage of the step from t = " in out


def test_reproduce_runs_a_long_run_in_a_process_of_its_own(tmp_path, monkeypatch):
    """So that the peak RSS the checkpoint records is the run's, not the reproduction's after
    its other steps (1,513 MiB once, for a run of ~415); a failing run raises with its output."""
    from redysim.reports.reproduce import Reproduction

    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path))
    rep = Reproduction(tmp_path, tmp_path / "out", 1, "quick")
    rep.say = lambda msg: None
    ck = rep._longrun(CASE, t_end=0.02, integrator="implicit", sample=0.01)
    assert float(ck["t"]) == 0.02 and str(ck["integrator"]) == "midpoint"
    assert (tmp_path / "longrun" / f"{CASE}-midpoint" / CHECKPOINT).exists()
    with pytest.raises(RuntimeError, match="exited 2"):
        rep._longrun(CASE, t_end=0.02, rtol=-1)


def test_a_long_run_records_its_own_peak_rss_not_its_parents(tmp_path):
    """ru_maxrss passes from parent to child across fork and exec: a long run the reproduction
    started recorded the reproduction's 1,522 MiB. VmHWM is the child's own (Linux)."""
    from redysim.harness.provenance import peak_rss_mib

    if not Path("/proc/self/status").exists():
        pytest.skip("no /proc: peak RSS is ru_maxrss here")
    ballast = np.ones(96 * 2 ** 20)  # 768 MiB of touched pages in this, the parent
    parent = peak_rss_mib()
    assert parent > 768
    out = tmp_path / "run"
    subprocess.run([sys.executable, "-m", "redysim.harness.longrun", CASE, "--t-end", "0.01",
                    "--out", str(out)], check=True, capture_output=True)
    del ballast
    child = float(load_checkpoint(out / CHECKPOINT)["peak_rss_mib"])
    assert child < parent - 500, (child, parent)


def test_a_finished_long_run_run_again_keeps_its_record(tmp_path):
    """Run again, a finished long run rewrote its checkpoint: the peak memory of a session that
    did nothing and Newton/GMRES counts of 0 over the run's own. Now its record is kept, byte
    for byte; and a resumed run's counts are the sum of its sessions'."""
    out = tmp_path / "out"
    kw = dict(t_end=0.02, integrator="implicit", sample=0.01, out=out, log=quiet)
    whole = run(CASE, every_s=1e9, **{**kw, "out": tmp_path / "whole"})
    assert int(whole["newton"]) > 0 and int(whole["krylov"]) > 0
    stopped = run(CASE, every_s=0.0, stop_after_s=0.0, **kw)
    assert str(stopped["status"]) == "stopped" and float(stopped["t"]) < 0.02
    done = run(CASE, every_s=1e9, **kw)
    assert str(done["status"]) == "done"
    for key in ("newton", "krylov", "steps", "nfev"):  # the two sessions: the whole run's
        assert int(done[key]) == int(whole[key]), key
    record = (out / CHECKPOINT).read_bytes()
    said = []
    again = run(CASE, every_s=1e9, **{**kw, "log": said.append})
    assert (out / CHECKPOINT).read_bytes() == record
    assert int(again["newton"]) == int(done["newton"]) > 0
    assert float(again["peak_rss_mib"]) == float(done["peak_rss_mib"])
    assert any("finished already" in m for m in said), said


def test_a_long_runs_missing_checkpoints_are_refused_by_name(tmp_path):
    """Its checkpoints deleted, a long run started over from t = 0 without a word; its manifest
    now tells: refused, naming the manifest and what to do."""
    out = tmp_path / "out"
    run("STUDY-R3", t_end=0.05, every_s=1e9, out=out, log=quiet)
    (out / CHECKPOINT).unlink()
    (out / PREVIOUS).unlink(missing_ok=True)
    with pytest.raises(LongrunError, match=r"manifest.json lists the checkpoints of this run.*"
                                           r"delete manifest.json"):
        run("STUDY-R3", t_end=0.05, every_s=1e9, out=out, log=quiet)
    # and with the manifest damaged too (hold-out battery 6: started over, writing over it)
    (out / "manifest.json").write_text("{bad json")
    with pytest.raises(LongrunError, match=r"manifest.json cannot be read \(damaged\) and no "
                                           r"checkpoint.*delete manifest.json"):
        run("STUDY-R3", t_end=0.05, every_s=1e9, out=out, log=quiet)
    assert (out / "manifest.json").read_text() == "{bad json"  # not written over


def _forge(out: Path, edit) -> None:
    """Edit the checkpoint's fields and record its new SHA-256 in the manifest, as a damage
    the digest cannot see (the damage written by the run's own code, or a forger)."""
    import hashlib
    import json

    with np.load(out / CHECKPOINT) as z:
        ck = {k: z[k] for k in z.files}
    edit(ck)
    with open(out / CHECKPOINT, "wb") as fh:
        np.savez(fh, **ck)
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["files"][CHECKPOINT] = hashlib.sha256((out / CHECKPOINT).read_bytes()).hexdigest()
    manifest["status"] = str(ck["status"])
    (out / "manifest.json").write_text(json.dumps(manifest))


@pytest.mark.parametrize("edit, fragment", [
    (lambda ck: ck.update(samples=np.zeros((2, 4)), status=np.array("in progress")),
     r"samples has shape \(2, 4\).*rows of 6 numbers"),
    (lambda ck: ck.update(status=np.array("xyz")), "status = 'xyz': not a long run's status"),
    (lambda ck: ck.update(case=np.array("STUDY-R5")), "case = 'STUDY-R5': this run is case "
                                                      "'STUDY-R3'"),
    (lambda ck: ck.update(steps=np.array(-5)), r"steps = -5: must be a count"),
    (lambda ck: ck.update(h=np.array(-1e-3)), r"h = -0.001: the next step must be"),
    (lambda ck: ck.update(samples=ck["samples"][::-1].copy()), "samples' times do not increase"),
], ids=["samples-4-columns", "status", "case-name", "steps", "h", "samples-order"])
def test_a_checkpoints_damaged_fields_are_refused_on_load(tmp_path, edit, fragment):
    """Battery 5 (F12): a checkpoint whose samples had 4 columns (its digest recomputed)
    resumed, ran to the end and failed writing the record, losing the work; a status 'xyz', the
    name of another case and steps = -5 were taken without a word. Each field is checked on
    load, as the run's own spec, and refused by name before any step."""
    out = tmp_path / "out"
    run("STUDY-R3", t_end=0.05, every_s=1e9, out=out, log=quiet)
    _forge(out, edit)
    said: list[str] = []
    with pytest.raises(LongrunError, match=fragment):
        run("STUDY-R3", t_end=0.05, every_s=1e9, out=out, log=said.append)
    assert not any("resuming" in m or "finished already" in m for m in said)
