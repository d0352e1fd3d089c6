"""Finished work kept honest (a fourth hold-out battery): a sweep's, a long run's and compare's
finished files are checked against what recorded them (their row, their manifest, their
horizon, their system), damaged ones redone or refused by name, and a path of the wrong kind
refused by name before any work."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from redysim.harness.spec import RunSpec
from redysim.harness.store import FolderError, read_parquet
from redysim.harness.sweep import (
    DAMAGED_DIR,
    RUNS_DIR,
    RUNS_FILE,
    SAMPLES_DIR,
    SAMPLES_FILE,
    run_sweep,
)

REPO = Path(__file__).resolve().parents[1]
PYTHON = sys.executable
SPECS = [RunSpec(case="STUDY-R3", t_end=0.2, sample=0.05),
         RunSpec(case="STUDY-R3", t_end=0.2, sample=0.05, integrator="dop853", rtol=1e-6,
                 atol=1e-8)]


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get(
        "PYTHONPATH", "")])}


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _fix_manifest(out: Path, run_id: str) -> None:
    """What a forger does: the manifest's SHA-256 recomputed for the edited files."""
    path = out / "manifest" / f"{run_id}.json"
    record = json.loads(path.read_text())
    record["files"] = {k: _sha(out / k) for k in record["files"]}
    path.write_text(json.dumps(record))


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("finished") / "out"
    run_sweep(SPECS, out, progress=False, workers=1)
    return out


def _copy(finished: Path, tmp_path: Path) -> Path:
    out = tmp_path / "out"
    shutil.copytree(finished, out)
    return out


# --------------------------------------------------------------------------- sweep: forgeries
@pytest.mark.parametrize("forgery", ["a samples row dropped", "no samples rows",
                                     "a samples column dropped", "a row column dropped"])
def test_a_forged_file_with_its_digest_recomputed_is_caught_by_its_row(finished, tmp_path,
                                                                       capsys, forgery):
    """Battery 4, item 3: samples/X with a row (or every row) dropped, or without tip_x, and
    runs/X without steps, each with the manifest's SHA-256 recomputed, were taken as finished:
    samples.parquet silently lacked rows, or held NaN. A run's samples are checked against its
    row (n_samples rows, every sample column), its row for every column a run writes."""
    out = _copy(finished, tmp_path)
    run_id = SPECS[0].run_id
    expected = read_parquet(out / SAMPLES_FILE)
    samples = out / SAMPLES_DIR / f"{run_id}.parquet"
    row = out / RUNS_DIR / f"{run_id}.parquet"
    if forgery == "a row column dropped":
        read_parquet(row).drop(columns=["steps"]).to_parquet(row, index=False)
    else:
        table = read_parquet(samples)
        table = {"a samples row dropped": table.iloc[:-1], "no samples rows": table.iloc[:0],
                 "a samples column dropped": table.drop(columns=["tip_x"])}[forgery]
        table.to_parquet(samples, index=False)
    _fix_manifest(out, run_id)
    runs = run_sweep(SPECS, out, progress=False, workers=1)
    assert runs.attrs["ran"] == 1
    err = capsys.readouterr().err
    assert str(out / "runs" if forgery == "a row column dropped" else samples) in err
    assert list((out / DAMAGED_DIR).iterdir())
    again = read_parquet(out / SAMPLES_FILE)
    assert len(again) == len(expected) and not again["tip_x"].isna().any()
    assert not read_parquet(out / RUNS_FILE)["steps"].isna().any()
    assert run_sweep(SPECS, out, progress=False, workers=1).attrs["ran"] == 0


def test_a_manifest_entry_outside_the_folder_is_never_looked_up(finished, tmp_path, capsys):
    """Battery 4: a manifest listing ../../../etc/passwd had it hashed. A run's manifest may
    list only its run's own two files; any other entry makes it a damaged manifest."""
    out = _copy(finished, tmp_path)
    run_id = SPECS[0].run_id
    path = out / "manifest" / f"{run_id}.json"
    record = json.loads(path.read_text())
    record["files"]["../../../etc/passwd"] = "0" * 64
    path.write_text(json.dumps(record))
    runs = run_sweep(SPECS, out, progress=False, workers=1)
    assert runs.attrs["ran"] == 1
    err = capsys.readouterr().err
    assert "../../../etc/passwd" in err and "not one of its run's files" in err


# --------------------------------------------------------------------------- sweep: wrong kinds
@pytest.mark.parametrize("where", [RUNS_FILE, SAMPLES_FILE, "sweep.json", "manifest/X.json",
                                   ".claims/X"])
def test_a_folder_where_a_sweep_file_goes_is_refused_by_name_before_any_run(
        finished, tmp_path, where):
    """Battery 4, item 6 and 'temp-file names': a folder at runs.parquet, sweep.json or
    .claims/<run> was a traceback or named the writer's temporary file after the runs, and
    manifest/X.json was said to be 'missing'. Each is refused by its own name, nothing run."""
    out = _copy(finished, tmp_path)
    run_id = SPECS[0].run_id
    (out / RUNS_DIR / f"{run_id}.parquet").unlink()  # a run left to do
    place = out / where.replace("X", run_id)
    if place.is_file():
        place.unlink()
    place.mkdir(parents=True, exist_ok=True)
    with pytest.raises(FolderError) as info:
        run_sweep(SPECS, out, progress=False, workers=1)
    assert str(place) in str(info.value) and "is a folder where a file goes" in str(info.value)
    assert ".tmp" not in str(info.value)
    assert not (out / RUNS_DIR / f"{run_id}.parquet").exists()  # nothing was run


def test_a_foreign_folder_among_the_claims_is_not_a_claim(finished, tmp_path):
    """Battery 4, item 6: a folder .claims/<id>.lock beside an unfinished run was an
    IsADirectoryError; it is no claim of a sweep's, and is left alone."""
    out = _copy(finished, tmp_path)
    run_id = SPECS[0].run_id
    (out / RUNS_DIR / f"{run_id}.parquet").unlink()
    (out / ".claims" / f"{run_id}.lock").mkdir(parents=True)
    runs = run_sweep(SPECS, out, progress=False, workers=1)
    assert runs.attrs["ran"] == 1 and (runs["status"] == "ok").all()


def test_the_resume_count_is_the_checked_one_and_said_once(tmp_path, capsys):
    """Battery 4: a resumed sweep printed '2 runs, 2 already done' and then ran one again (the
    count was of files present, not of files checked), and its notes came twice."""
    from redysim.harness.cli import main

    out = tmp_path / "out"
    sweep = tmp_path / "s.toml"
    sweep.write_text('[sweep]\nname = "s"\ncases = ["STUDY-R3"]\nrtols = [1e-4, 1e-6]\n'
                     't_end = 0.2\nsample = 0.05\n')
    argv = ["sweep", str(sweep), "--out", str(out), "--no-progress", "--workers", "1"]
    assert main(argv) == 0
    (victim,) = list((out / SAMPLES_DIR).glob("*.parquet"))[:1]
    victim.unlink()
    capsys.readouterr()
    assert main(argv) == 0
    res = capsys.readouterr()
    assert "2 runs, 1 already done" in res.out and "1 run by this sweep" in res.out, res.out
    assert res.err.count(f"{victim} is missing") == 1, res.err


def _unwritable(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """A redysim command in a process that file permissions bind (root's override dropped)."""
    cmd = [PYTHON, "-m", "redysim.reports.commands", *argv]
    if os.geteuid() == 0:
        cmd = ["setpriv", "--bounding-set=-dac_override,-dac_read_search,-fowner", *cmd]
    return subprocess.run(cmd, cwd=cwd, env=_env(), capture_output=True, text=True,
                          timeout=600)


@pytest.mark.skipif(os.geteuid() == 0 and not shutil.which("setpriv"),
                    reason="as root, a read-only folder needs setpriv to drop the override")
def test_a_read_only_samples_folder_with_a_damaged_file_is_refused_by_name(tmp_path):
    """Battery 4, item 7: a read-only samples/ holding a damaged file was a PermissionError
    from setting it aside. The sweep sees it cannot repair there and refuses by name."""
    sweep = tmp_path / "s.toml"
    sweep.write_text('[sweep]\nname = "s"\ncases = ["STUDY-R3"]\nt_end = 0.05\n'
                     'sample = 0.05\n')
    out = tmp_path / "out"
    ok = _unwritable(["sweep", str(sweep), "--out", str(out), "--no-progress"], tmp_path)
    assert ok.returncode == 0, ok.stderr
    (victim,) = (out / SAMPLES_DIR).glob("*.parquet")
    with open(victim, "r+b") as fh:
        fh.truncate(10)
    (out / SAMPLES_DIR).chmod(0o555)
    try:
        res = _unwritable(["sweep", str(sweep), "--out", str(out), "--no-progress"], tmp_path)
    finally:
        (out / SAMPLES_DIR).chmod(0o755)
    assert res.returncode == 2 and "Traceback" not in res.stderr, res.stderr
    assert str(out / SAMPLES_DIR) in res.stderr and "cannot be written" in res.stderr


# --------------------------------------------------------------------------- long runs
LONG_CASE, LONG_T = "RE-U125-L1", 0.05


@pytest.fixture(scope="module")
def long_done(tmp_path_factory) -> Path:
    from redysim.harness.longrun import run

    out = tmp_path_factory.mktemp("long") / "out"
    run(LONG_CASE, t_end=LONG_T, out=out, log=lambda _m: None)
    return out


def _forge_checkpoint(out: Path, **changes) -> None:
    """Edit the checkpoint's arrays and recompute its SHA-256 in manifest.json."""
    path = out / "checkpoint.npz"
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays.update({k: np.asarray(v) for k, v in changes.items()})
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    record = json.loads((out / "manifest.json").read_text())
    record["files"]["checkpoint.npz"] = _sha(path)
    (out / "manifest.json").write_text(json.dumps(record))


@pytest.mark.parametrize("forgery", ["t past t_end, done", "done before t_end", "t < 0",
                                     "y two entries short"])
def test_a_forged_checkpoint_is_refused_by_name(long_done, tmp_path, forgery):
    """Battery 4, items 4 and 11: a checkpoint with t = 5 (of 0.05) was accepted as 'done, t =
    5'; 'done' at t short of t_end as finished; t = -1 resumed from -1; y two entries short was
    a shape-mismatch ValueError from inside the integrator. Each is refused naming the file,
    the field and its value, with the way out."""
    from redysim.harness.longrun import LongrunError, run

    out = tmp_path / "out"
    shutil.copytree(long_done, out)
    with np.load(out / "checkpoint.npz") as z:
        y = z["y"]
    changes = {"t past t_end, done": {"t": 5.0},
               "done before t_end": {"t": LONG_T / 2},
               "t < 0": {"t": -1.0, "status": "stopped"},
               "y two entries short": {"y": y[:-2], "status": "stopped", "t": LONG_T / 2}}
    _forge_checkpoint(out, **changes[forgery])
    with pytest.raises(LongrunError) as info:
        run(LONG_CASE, t_end=LONG_T, out=out, log=lambda _m: None)
    msg = str(info.value)
    assert str(out / "checkpoint.npz") in msg and "another --out" in msg
    assert ("shape" in msg) if forgery.startswith("y") else ("t = " in msg)


@pytest.mark.parametrize("name", ["manifest.json", "checkpoint.npz"])
def test_a_folder_where_a_long_runs_file_goes_is_refused_before_any_step(tmp_path, name):
    """Battery 4: a long run with manifest.json a folder ran all the way, then failed naming a
    temporary file. Refused by its name before any step."""
    from redysim.harness.longrun import run
    from redysim.harness.store import FolderError

    out = tmp_path / "out"
    (out / name).mkdir(parents=True)
    said: list[str] = []
    with pytest.raises(FolderError) as info:
        run(LONG_CASE, t_end=LONG_T, out=out, log=said.append)
    assert str(out / name) in str(info.value) and ".tmp" not in str(info.value)
    assert not said  # (no step was taken: nothing was said of the run)


# --------------------------------------------------------------------------- compare's cache
REF_T, REF_DT = 0.1, 0.05


@pytest.fixture
def cached(tmp_path, monkeypatch):
    """STUDY-R3's reference computed into a fresh results folder: (scenario, its path, ref)."""
    from redysim.harness.reference import compute_reference, reference_path
    from redysim.io.scenarios import load_scenario

    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path / "results"))
    scn = load_scenario("STUDY-R3")
    ref = compute_reference(scn, REF_T, REF_DT)
    return scn, reference_path(scn, REF_T, REF_DT), ref


def _rewrite(path: Path, **changes) -> None:
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays.update(changes)
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


@pytest.mark.parametrize("damage", ["tip + 0.5 m", "y cut to 4 columns", "a NaN in tip",
                                    "one sample"])
def test_a_damaged_cached_reference_is_said_and_recomputed(cached, capsys, damage):
    """Battery 4, items 5 and 8: compare trusted its reference cache: 0.5 added to its tip
    made every run report an error of 0.87 m; a NaN or one-sample reference gave NaN errors
    and '0 failed'; y cut to 4 columns failed every run, then a KeyError. The cache has a
    digest beside each file and its arrays are checked against the scenario (shapes, samples
    from 0 to the horizon, finite); a damaged one is said and recomputed."""
    from redysim.harness.reference import compute_reference, load_reference

    scn, path, ref = cached
    with np.load(path) as z:
        t, tip, y = z["t"], z["tip"], z["y"]
    changes = {"tip + 0.5 m": {"tip": tip + 0.5}, "y cut to 4 columns": {"y": y[:, :4]},
               "a NaN in tip": {"tip": np.where(np.arange(tip.size).reshape(tip.shape) == 4,
                                                np.nan, tip)},
               "one sample": {"t": t[:1], "y": y[:1], "tip": tip[:1]}}[damage]
    _rewrite(path, **changes)
    assert load_reference(scn, REF_T, REF_DT) is None
    assert f"{path} is damaged" in capsys.readouterr().err
    again = compute_reference(scn, REF_T, REF_DT)
    np.testing.assert_array_equal(again.tip, ref.tip)  # (the same computation, done again)
    assert load_reference(scn, REF_T, REF_DT) is not None


def test_a_file_where_the_reference_cache_goes_is_refused_by_name(tmp_path, monkeypatch):
    """Battery 4, item 9: results/reference a file was a FileExistsError from deep inside."""
    from redysim.harness.reference import compute_reference, results_dir
    from redysim.io.scenarios import load_scenario

    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path / "results"))
    results_dir().mkdir()
    (results_dir() / "reference").write_text("x")
    with pytest.raises(FolderError) as info:
        compute_reference(load_scenario("STUDY-R3"), REF_T, REF_DT)
    assert str(results_dir() / "reference") in str(info.value)
    assert "is a file where a folder goes" in str(info.value)


@pytest.mark.parametrize("where", ["compare.pdf", "compare.html", "reference"])
def test_compare_refuses_a_wrong_kind_of_path_by_name_before_any_engine(tmp_path, monkeypatch,
                                                                       where):
    """Battery 4, items 9 and 10: compare.pdf a folder was an IsADirectoryError from the PDF
    writer after every run; the reference's .npz a folder failed after all the runs. Each is
    refused by name before the engines are asked anything."""
    from redysim.harness.reference import reference_path
    from redysim.io.scenarios import load_scenario
    from redysim.reports.compare import compare

    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path / "results"))
    out = tmp_path / "cmp"
    scn = load_scenario("STUDY-R3")
    place = (reference_path(scn, 0.01, scn.sample_for(0.01)) if where == "reference"
             else out / where)
    place.mkdir(parents=True)
    said: list[str] = []
    with pytest.raises(FolderError) as info:
        compare("STUDY-R3", out, t_end=0.01, engines=["mujoco"], progress=False,
                log=said.append)
    assert str(place) in str(info.value) and not said


def test_advice_without_any_measured_run_is_no_advice():
    """Battery 4, item 8: every run failed (no max_tip_err column) -> KeyError in advice."""
    from redysim.reports.compare import advice

    runs = pd.DataFrame([{"run_id": "a", "status": "failed", "reason": "worker raised"}])
    assert all(a["best"] is None and not a["per_engine"] for a in advice(runs))


def test_advise_onto_a_file_refuses_before_saying_it_caches_there(tmp_path, capsys):
    """Battery 4: 'advise ... --out FILE' printed 'runs cached in FILE' before refusing."""
    from redysim.harness.cli import main

    a_file = tmp_path / "a-file"
    a_file.write_text("x")
    assert main(["advise", "RE-U125-L1", "--tip-tol", "1e-3", "--out", str(a_file)]) == 2
    res = capsys.readouterr()
    assert "runs cached" not in res.out + res.err and str(a_file) in res.err


def _snapshot(folder: Path) -> dict:
    """Every file and folder under ``folder`` (hidden ones too): its size and mtime."""
    return {str(p.relative_to(folder)): (p.is_dir(), p.stat().st_size if p.is_file() else 0,
                                         p.stat().st_mtime_ns)
            for p in sorted(folder.rglob("*"))}


@pytest.mark.engine
def test_a_finished_compare_is_read_as_it_is_even_where_it_cannot_write(tmp_path, monkeypatch):
    """Battery 5 (F7): compare run again on a finished folder rewrote compare.html, compare.pdf
    and .claims, and refused a finished folder it could not write. Now it says the record and
    writes nothing, as sweep and longrun do; a damaged page is built again."""
    pytest.importorskip("mujoco")
    import redysim.harness.store as store
    from redysim.reports.compare import compare

    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path / "results"))
    out = tmp_path / "cmp"
    kw = dict(t_end=0.01, engines=["mujoco"], progress=False, workers=1)
    compare("STUDY-R3", out, log=lambda s: None, **kw)
    before = _snapshot(out)
    said: list[str] = []

    def refuse(folder, **_):  # a folder that cannot be written (chattr +i, a read-only mount)
        raise FolderError(f"{str(folder)!r}: the results folder cannot be written")

    monkeypatch.setattr(store, "check_writable", refuse)
    assert compare("STUDY-R3", out, log=said.append, **kw) == (out / "compare.html",
                                                                out / "compare.pdf")
    assert _snapshot(out) == before
    assert len(said) == 1 and "finished in" in said[0] and "nothing rewritten" in said[0]
    (out / "compare.html").write_text("damaged")  # not the page recorded: refused read-only,
    with pytest.raises(FolderError, match="cannot be written"):
        compare("STUDY-R3", out, log=said.append, **kw)
    monkeypatch.undo()
    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path / "results"))
    compare("STUDY-R3", out, log=said.append, **kw)  # and built again where it can write
    assert "Single-state agreement" in (out / "compare.html").read_text()


def test_compare_refuses_a_reference_cache_it_cannot_write_before_any_work(tmp_path,
                                                                           monkeypatch):
    """Battery 5 (F8): a read-only $REDYSIM_RESULTS was refused after the reference was
    computed, and the message said to give another --out, which does not move the cache. Now
    refused before any engine is asked, naming REDYSIM_RESULTS."""
    import redysim.harness.reference as reference
    from redysim.reports.compare import compare

    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path / "results"))

    def read_only(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(reference, "probe_write", read_only)  # (chattr +i: root writes else)
    said: list[str] = []
    with pytest.raises(FolderError) as info:
        compare("STUDY-R3", tmp_path / "cmp", t_end=0.01, engines=["mujoco"], progress=False,
                log=said.append)
    msg = str(info.value)
    assert str(tmp_path / "results" / "reference") in msg and "Permission denied" in msg
    assert "set REDYSIM_RESULTS to a folder you can write" in msg and "(--out)" not in msg
    assert not said  # before the engines' agreement, the first work
