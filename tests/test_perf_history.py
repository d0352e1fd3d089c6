"""The performance history (redysim.reports.history): appends keep every earlier run, a dirty
tree is marked (the history file itself not counting), a torn last line leaves the file
readable, a missing or empty file is no history, and the report's figure is drawn from one
commit and from several. No timings: the benchmark documents here are made up."""

from __future__ import annotations

import json
import subprocess

import pytest

from redysim.reports import history as H

pytest.importorskip("matplotlib")

CPU = "Test CPU"


def bench_doc(ns_200=50.0, ns_100k=45.0, ns_batch=16.0, *, date="2026-11-26T10:00:00+00:00",
              cpu=CPU, commit_info=None) -> dict:
    """A pytest-benchmark JSON of make bench's followed benchmarks, times from ns/DOF."""
    def bench(name, dof, ns, states=1, **extra):
        s = ns * dof * states * 1e-9
        return {"name": name, "stats": {"min": s, "median": 1.1 * s, "rounds": 7},
                "extra_info": {"cpu": cpu, "cores": 2, "python": "3.11.7", "numpy": "2.4.6",
                               "numba": "0.68.1", "redysim": "0.1.0", "dof": dof,
                               "states": states, "engine": "redysim rge-a", **extra}}
    return {"datetime": date, "machine_info": {"cpu": {"brand_raw": cpu, "count": 2}},
            "commit_info": commit_info or {},
            "benchmarks": [
                bench("test_rge_a_u_chain[200]", 200, ns_200),
                bench("test_rge_a_u_chain[100000]", 100_000, ns_100k),
                bench("test_rge_a_batch_u_chain[1-thread]", 250, ns_batch, states=64,
                      kind="batch", threads=1),
                {"name": "no_dof", "stats": {"min": 1.0, "median": 1.0, "rounds": 1},
                 "extra_info": {}}]}


def record(commit="a" * 40, dirty=False, commit_date="2026-11-26T09:00:00+00:00", **kw):
    git = {"commit": commit, "commit_date": commit_date, "dirty": dirty}
    return H.run_record(bench_doc(**kw), "core", git)


def test_a_record_has_the_machine_and_each_benchmark_with_its_dof():
    rec = record()
    assert rec["machine"]["cpu"] == CPU and rec["machine"]["numba"] == "0.68.1"
    assert [b["name"] for b in rec["benchmarks"]] == [
        "test_rge_a_u_chain[200]", "test_rge_a_u_chain[100000]",
        "test_rge_a_batch_u_chain[1-thread]"]  # one without a DOF is not a figure per DOF
    df = H.to_frame([rec])
    assert set(df["stat"]) == {"min", "median"}
    batch = df[(df["kind"] == "batch") & (df["stat"] == "min")].iloc[0]
    assert batch["unit"] == "ns/DOF/state" and batch["value"] == pytest.approx(16.0)
    assert batch["threads"] == 1
    single = df[(df["benchmark"] == "test_rge_a_u_chain[200]") & (df["stat"] == "median")]
    assert single["unit"].iloc[0] == "ns/DOF" and single["value"].iloc[0] == pytest.approx(55.0)


def test_appending_keeps_earlier_runs_byte_for_byte(tmp_path):
    path = tmp_path / "history" / "bench.jsonl"
    first = record(date="2026-11-26T10:00:00+00:00")
    assert H.append(first, path)
    before = path.read_bytes()
    second = record(commit="b" * 40, date="2026-11-27T10:00:00+00:00")
    assert H.append(second, path)
    assert path.read_bytes().startswith(before)
    runs, bad = H.read_runs(path)
    assert [r["run_id"] for r in runs] == [first["run_id"], second["run_id"]] and bad == 0
    assert not H.append(first, path), "the same run is recorded once"
    assert len(H.read_runs(path)[0]) == 2


def test_a_dirty_tree_is_marked_and_the_history_itself_does_not_count(tmp_path):
    repo = tmp_path / "repo"
    (repo / "benchmarks" / "history").mkdir(parents=True)
    (repo / "code.py").write_text("x = 1\n")
    (repo / "benchmarks" / "history" / "bench.jsonl").write_text("")

    def git(*args):
        subprocess.run(["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@t",
                        *args], check=True, capture_output=True)

    git("init", "-q")
    git("add", ".")
    git("commit", "-q", "-m", "first")
    clean = H.git_state(repo)
    assert len(clean["commit"]) == 40 and clean["dirty"] is False and clean["commit_date"]
    H.append(record(commit=clean["commit"]), repo / "benchmarks" / "history" / "bench.jsonl")
    assert H.git_state(repo)["dirty"] is False, "a run appended does not dirty the next"
    (repo / "code.py").write_text("x = 2\n")
    assert H.git_state(repo)["dirty"] is True
    assert H.git_state(tmp_path / "not-a-repo") == {"commit": "", "commit_date": "",
                                                    "dirty": None}


def test_a_json_from_another_commit_keeps_the_commit_it_ran_at(tmp_path):
    ran_at = {"id": "c" * 40, "time": "2026-11-20T08:00:00+00:00", "dirty": True}
    src = tmp_path / "core.json"
    src.write_text(json.dumps(bench_doc(commit_info=ran_at)))
    rec, new = H.append_json(src, history=tmp_path / "h.jsonl", repo=tmp_path)  # not git
    assert new and rec["suite"] == "core"
    assert (rec["commit"], rec["commit_date"], rec["dirty"]) == ("c" * 40, ran_at["time"], True)


def test_a_torn_last_line_leaves_the_file_readable_and_the_next_append_whole(tmp_path):
    path = tmp_path / "bench.jsonl"
    first = record()
    H.append(first, path)
    line = json.dumps(record(commit="b" * 40), separators=(",", ":"))
    with open(path, "a", encoding="utf-8") as fh:  # a writer killed mid-line
        fh.write(line[: len(line) // 2])
    runs, bad = H.read_runs(path)
    assert [r["run_id"] for r in runs] == [first["run_id"]] and bad == 1
    third = record(commit="d" * 40, date="2026-11-28T10:00:00+00:00")
    assert H.append(third, path)
    runs, bad = H.read_runs(path)
    assert [r["run_id"] for r in runs] == [first["run_id"], third["run_id"]] and bad == 1
    assert H.history_figure(path).png is not None
    assert "1 unreadable line(s) skipped" in H.history_figure(path).caption


@pytest.mark.parametrize("content", [None, "", "\n\n", "not json\n"])
def test_a_missing_or_empty_history_is_no_history(tmp_path, content):
    path = tmp_path / "bench.jsonl"
    if content is not None:
        path.write_text(content)
    df = H.read(path)
    assert df.empty and list(df.columns) == list(H.COLUMNS)
    fig = H.history_figure(path)
    assert fig.png is None and fig.not_run == H.NO_HISTORY
    assert H.main(["--history", str(path), "show"]) == 0


def test_the_figure_from_one_commit_says_a_step_needs_a_second(tmp_path):
    path = tmp_path / "bench.jsonl"
    H.append(record(), path)
    H.append(record(date="2026-11-26T11:00:00+00:00", ns_200=52.0), path)  # a second run
    fig = H.history_figure(path)
    assert fig.png is not None and fig.png.startswith(b"\x89PNG")
    assert fig.id == "perf-history" and "one commit so far (2 run(s))" in fig.caption


def test_the_figure_from_several_commits_and_machines(tmp_path):
    path = tmp_path / "bench.jsonl"
    commits = [(c * 40, f"2026-11-2{i}T09:00:00+00:00") for i, c in enumerate("abcd", 1)]
    for i, (commit, cdate) in enumerate(commits):
        for cpu in (CPU, "Other CPU"):
            H.append(record(commit=commit, commit_date=cdate, cpu=cpu,
                            date=f"2026-11-2{i + 1}T10:00:00+00:00",
                            ns_200=50.0 + 20 * (i >= 2)), path)  # a step at the third commit
    H.append(record(commit=commits[-1][0], commit_date=commits[-1][1], dirty=True,
                    date="2026-11-29T10:00:00+00:00"), path)
    order = H.commit_order(H.read(path))
    assert list(order["label"]) == ["aaaaaaa", "bbbbbbb", "ccccccc", "ddddddd", "ddddddd+"]
    fig = H.history_figure(path)
    assert fig.png is not None and "9 runs of 4 commits" in fig.caption
    out = tmp_path / "fig.png"
    assert H.main(["--history", str(path), "plot", str(out)]) == 0 and out.is_file()


def test_the_report_carries_the_history_figure(tmp_path):
    from redysim.reports.build import build_report
    from redysim.reports.results import Results

    path = tmp_path / "bench.jsonl"
    H.append(record(), path)
    report = build_report(Results(tmp_path / "results"), path)
    figs = {f.id: f for f in report.figures()}
    assert figs["perf-history"].png is not None
    empty = build_report(Results(tmp_path / "results"), tmp_path / "missing.jsonl")
    assert {f.id: f for f in empty.figures()}["perf-history"].not_run == H.NO_HISTORY
