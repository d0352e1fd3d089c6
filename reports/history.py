"""The performance history: every ``make bench`` and ``make bench-engines`` run, kept for good.

    python -m redysim.reports.history append results/bench/core.json    # make bench does this
    python -m redysim.reports.history show [--last 10]                  # the followed figures
    python -m redysim.reports.history plot history.png                  # the report's figure

The file, ``benchmarks/history/bench.jsonl`` in the checkout (:data:`HISTORY_FILE`), is tracked
by git and committed by the developer: it survives ``make clean`` (which removes ``results/``)
and travels with the branches, whose appended lines ``.gitattributes`` merges as a union. One
JSON line per run (JSON Lines): the run's commit, the commit's date, whether the tree had
uncommitted changes (``dirty``; the history folder itself does not count, or the first append
would mark every later run), the run's date, its suite (``core`` or ``engines``: the name of the
pytest-benchmark JSON), the machine (CPU model, cores, Python, numpy, numba, redysim) and, per
benchmark, its name, engine, kind, DOF, states, rounds and fastest and median round in seconds.
One line per run makes a run all or nothing, and names the machine once.

Appends never touch what is there: the line goes to the end of the file in one ``write`` on a
descriptor opened ``O_APPEND`` and locked (``flock``) against a second appender, then is fsynced.
A process killed mid-write leaves at most a partial last line; the reader skips (and counts)
lines that are not a whole record, and the next append starts on a line of its own. A run
appended twice (the same suite, date, commit and CPU) is recorded once.

:func:`read` gives one row per benchmark figure and statistic (``min``, ``median``): ``value`` in
ns per DOF, per DOF and state for a batch (``unit``). :func:`history_figure` draws the figures
the issue follows (:data:`PANELS`) across commits for the report (redysim.reports.build).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import hashlib
import json
import os
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING

from redysim.harness.provenance import REPO

if TYPE_CHECKING:
    import pandas as pd

    from .content import Figure

HISTORY_DIR = Path("benchmarks") / "history"  # relative to the checkout
HISTORY_FILE = REPO / HISTORY_DIR / "bench.jsonl"
SCHEMA = 1
STATS = ("min", "median")
FOLLOWED_STAT = "min"  # the fastest round: this shared VM only ever adds time (README)
MACHINE_KEYS = ("cpu", "cores", "python", "numpy", "numba", "redysim")
COLUMNS = ("run_id", "suite", "date", "commit", "commit_date", "dirty", *MACHINE_KEYS,
           "machine", "benchmark", "engine", "kind", "dof", "states", "threads", "rounds",
           "stat", "seconds", "value", "unit")
NO_HISTORY = ("no performance history yet: make bench appends a line per run to "
              "benchmarks/history/bench.jsonl")


@dataclass(frozen=True)
class Panel:
    """One followed figure: a benchmark of a suite, drawn in a panel of its own."""

    title: str
    suite: str
    benchmark: str


PANELS = (
    Panel("qdd per call, 200 DOF", "core", "test_rge_a_u_chain[200]"),
    Panel("qdd per call, 100,000 DOF", "core", "test_rge_a_u_chain[100000]"),
    Panel("batch of 64 states, 250 DOF, one thread", "core",
          "test_rge_a_batch_u_chain[1-thread]"),
    Panel("batch of 64 Talos states, one thread", "core", "test_rge_a_batch_robot[talos]"),
)


# --------------------------------------------------------------------------- writing
def git_state(repo: str | os.PathLike = REPO) -> dict:
    """The checkout's commit (full hash), its committer date, and whether tracked files other
    than the history folder have uncommitted changes; ``""``/``None`` outside git."""
    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(repo), *args], capture_output=True, text=True,
                              timeout=10, check=True).stdout.strip()

    try:
        commit = git("rev-parse", "HEAD")
        date = git("show", "-s", "--format=%cI", "HEAD")
        changed = git("status", "--porcelain", "--untracked-files=no", "--", ".",
                      f":(exclude){HISTORY_DIR.as_posix()}")
    except (OSError, subprocess.SubprocessError):
        return {"commit": "", "commit_date": "", "dirty": None}
    return {"commit": commit, "commit_date": date, "dirty": bool(changed)}


def _installed(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return ""


def machine_of(doc: dict) -> dict:
    """The machine and versions of a pytest-benchmark JSON: its benchmarks' own record
    (benchmarks/conftest.py's ``machine()``) where it has them, else pytest-benchmark's
    ``machine_info``, else this interpreter's versions (``make`` appends from the venv that ran
    the benchmarks)."""
    extra: dict = {}
    for b in doc.get("benchmarks", []):
        extra.update({k: v for k, v in b.get("extra_info", {}).items() if k not in extra})
    info = doc.get("machine_info", {})
    cpu = extra.get("cpu") or extra.get("processor")
    if not cpu or cpu == "unknown":
        cpu = info.get("cpu", {}).get("brand_raw") or info.get("processor") or "unknown"
    cores = extra.get("cores") or extra.get("cpus") or info.get("cpu", {}).get("count")
    out = {"cpu": str(cpu), "cores": int(cores) if cores else None,
           "python": extra.get("python") or info.get("python_version", "")}
    for pkg in ("numpy", "numba", "redysim"):
        out[pkg] = str(extra.get(pkg) or _installed(pkg))
    return out


def run_record(doc: dict, suite: str, git: dict, machine: dict | None = None) -> dict:
    """One history line from a pytest-benchmark JSON: every benchmark that says its DOF."""
    machine = machine or machine_of(doc)
    benches = []
    for b in doc.get("benchmarks", []):
        x = b.get("extra_info", {})
        if "dof" not in x:
            continue
        s = b["stats"]
        row = {"name": b["name"], "engine": str(x.get("engine", "")),
               "kind": str(x.get("kind", "qdd")), "dof": int(x["dof"]),
               "states": int(x.get("states", 1)), "rounds": int(s["rounds"]),
               **{f"{k}_s": float(s[k]) for k in STATS}}
        for key in ("threads", "robot"):
            if key in x:
                row[key] = x[key]
        benches.append(row)
    date = doc.get("datetime") or _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    key = json.dumps([suite, date, git.get("commit", ""), machine.get("cpu", "")])
    return {"schema": SCHEMA, "run_id": hashlib.sha256(key.encode()).hexdigest()[:16],
            "suite": suite, "date": date, **git, "machine": machine, "benchmarks": benches}


def _lock(fd: int) -> None:
    try:
        import fcntl
    except ImportError:  # not POSIX: appends are still whole lines, one writer assumed
        return
    fcntl.flock(fd, fcntl.LOCK_EX)


def _read_all(fd: int) -> bytes:
    chunks, offset = [], 0
    while chunk := os.pread(fd, 1 << 20, offset):
        chunks.append(chunk)
        offset += len(chunk)
    return b"".join(chunks)


def append(record: dict, path: str | os.PathLike = HISTORY_FILE) -> bool:
    """Append ``record`` as one line to the history ``path``; False (and nothing written) when
    a run of the same ``run_id`` is there already. Earlier lines are never rewritten."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    line = json.dumps(record, separators=(",", ":")) + "\n"
    fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o666)
    try:
        _lock(fd)  # released by close
        old = _read_all(fd)
        if record["run_id"] in {r["run_id"] for r in _records(old)[0]}:
            return False
        if old and not old.endswith(b"\n"):  # a line torn by a crash: leave it on its own
            line = "\n" + line
        data = line.encode("utf-8")
        while data:
            data = data[os.write(fd, data):]
        os.fsync(fd)
    finally:
        os.close(fd)
    return True


def append_json(bench_json: str | os.PathLike, *, suite: str | None = None,
                history: str | os.PathLike = HISTORY_FILE,
                repo: str | os.PathLike = REPO) -> tuple[dict, bool]:
    """Append the run of a pytest-benchmark JSON file (suite: the file's stem) to ``history``,
    with the git state of ``repo``; the record and whether it was new.

    A JSON whose run pytest-benchmark recorded at another commit than ``repo``'s (an old file
    appended late) keeps that commit, its date and pytest-benchmark's own ``dirty`` (which,
    unlike :func:`git_state`'s, counts a changed history file too)."""
    path = Path(bench_json)
    doc = json.loads(path.read_text(encoding="utf-8"))
    git = git_state(repo)
    ran_at = doc.get("commit_info", {})
    if ran_at.get("id") not in (None, "", "unversioned", git["commit"]):
        git = {"commit": ran_at["id"], "commit_date": ran_at.get("time") or "",
               "dirty": bool(ran_at.get("dirty"))}
    record = run_record(doc, suite or path.stem, git)
    return record, append(record, history)


# --------------------------------------------------------------------------- reading
def _records(data: bytes) -> tuple[list[dict], int]:
    """The whole records of a history file's bytes (the first of each run_id), and how many
    non-blank lines were not one (a torn append, a merge gone wrong)."""
    out, seen, bad = [], set(), 0
    for raw in data.split(b"\n"):
        if not raw.strip():
            continue
        try:
            rec = json.loads(raw)
        except (json.JSONDecodeError, UnicodeDecodeError):
            bad += 1
            continue
        if not (isinstance(rec, dict) and isinstance(rec.get("benchmarks"), list)
                and "run_id" in rec):
            bad += 1
            continue
        if rec["run_id"] not in seen:
            seen.add(rec["run_id"])
            out.append(rec)
    return out, bad


def read_runs(path: str | os.PathLike = HISTORY_FILE) -> tuple[list[dict], int]:
    """The runs in the history ``path`` (none when it is missing or empty) and the number of
    unreadable lines skipped."""
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        return [], 0
    return _records(data)


def to_frame(runs: Sequence[dict]) -> pd.DataFrame:
    """One row per run, benchmark and statistic (:data:`COLUMNS`)."""
    import pandas as pd

    rows = []
    for r in runs:
        m = r.get("machine", {})
        base = {"run_id": r["run_id"], "suite": r.get("suite", ""), "date": r.get("date", ""),
                "commit": r.get("commit", ""), "commit_date": r.get("commit_date", ""),
                "dirty": bool(r.get("dirty")), **{k: m.get(k) for k in MACHINE_KEYS},
                "machine": f"{m.get('cpu', 'unknown')}, {m.get('cores', '?')} cores"}
        for b in r["benchmarks"]:
            per = b["dof"] * b.get("states", 1)
            for stat in STATS:
                if f"{stat}_s" not in b:
                    continue
                rows.append({**base, "benchmark": b["name"], "engine": b.get("engine", ""),
                             "kind": b.get("kind", "qdd"), "dof": b["dof"],
                             "states": b.get("states", 1), "threads": b.get("threads"),
                             "rounds": b.get("rounds"), "stat": stat,
                             "seconds": b[f"{stat}_s"], "value": b[f"{stat}_s"] * 1e9 / per,
                             "unit": "ns/DOF/state" if b.get("states", 1) > 1 else "ns/DOF"})
    df = pd.DataFrame(rows, columns=list(COLUMNS))
    for col in ("date", "commit_date"):
        df[col] = pd.to_datetime(df[col], utc=True, errors="coerce", format="ISO8601")
    return df


def read(path: str | os.PathLike = HISTORY_FILE) -> pd.DataFrame:
    """The history as a table, one row per figure and statistic; empty (with the columns) when
    the file is missing or empty."""
    return to_frame(read_runs(path)[0])


def commit_order(df: pd.DataFrame) -> pd.DataFrame:
    """The (commit, dirty) pairs of ``df`` in the order they were made: by commit date, a
    dirty tree after its commit's clean runs, then by first run; columns commit, dirty,
    commit_date, first, x (0, 1, ...) and label (short hash, ``+`` for a dirty tree)."""
    import pandas as pd

    if df.empty:
        return pd.DataFrame(columns=["commit", "dirty", "commit_date", "first", "x", "label"])
    g = (df.groupby(["commit", "dirty"], as_index=False, dropna=False)
         .agg(commit_date=("commit_date", "min"), first=("date", "min")))
    g = g.sort_values(["commit_date", "dirty", "first"], na_position="last", kind="stable")
    g = g.reset_index(drop=True)
    g["x"] = range(len(g))
    g["label"] = [(c[:7] or "no git") + ("+" if d else "") for c, d in
                  zip(g["commit"], g["dirty"], strict=True)]
    return g


# --------------------------------------------------------------------------- the figure
FIG_ID, FAMILY, TITLE = "perf-history", "perf-history", "Performance history"
MAX_TICKS = 16


def _shown(path: str | os.PathLike) -> str:
    """``path`` as the reader knows it: relative to the checkout when inside it."""
    try:
        return Path(path).resolve().relative_to(REPO).as_posix()
    except ValueError:
        return str(path)


def history_figure(path: str | os.PathLike = HISTORY_FILE) -> Figure:
    """The followed figures (:data:`PANELS`) across commits: one marker per run, a colour per
    machine, hollow for a dirty tree, a line through each commit's fastest clean run per
    machine. Without history: a figure without image that says so."""
    import numpy as np
    from matplotlib.lines import Line2D

    from .figures import PANEL_H, PANEL_W, _figure, missing, new_figure
    from .text import provenance_line

    runs, bad = read_runs(path)
    df = to_frame(runs)
    shown = _shown(path)
    caption = (f"ns per DOF of one qdd call at 200 and 100,000 DOF (U chains) and per DOF and "
               f"state of a 64-state batch at 250 DOF and of Talos (38 DOF, a tree's tiles) on "
               f"one thread, the fastest round of each "
               f"run ({FOLLOWED_STAT}), for every make bench run recorded in "
               f"{shown}; commits in the order they were made "
               f"(commit date), one marker per run, a colour per machine, hollow for a tree "
               f"with uncommitted changes (its commit's hash with +), a line through each "
               f"commit's fastest run on a machine. A regression is a step "
               f"up from one commit to the next on the same machine; runs of one commit "
               f"spread with the machine's load.")
    if bad:
        caption += f" {bad} unreadable line(s) skipped (a torn append)."
    sel = df[(df["stat"] == FOLLOWED_STAT)
             & (df["suite"] + "::" + df["benchmark"]).isin([f"{p.suite}::{p.benchmark}"
                                                           for p in PANELS])]
    if sel.empty:
        return missing(FIG_ID, FAMILY, TITLE, caption, NO_HISTORY)
    order = commit_order(sel)
    n_commits = order["commit"].nunique()
    n_runs = sel["run_id"].nunique()
    if n_commits < 2:
        caption += (f" The history has one commit so far ({n_runs} run(s)): a step needs a "
                    f"second.")
    else:
        caption += f" {n_runs} runs of {n_commits} commits."
    x_of = {(c, d): x for c, d, x in zip(order["commit"], order["dirty"], order["x"],
                                         strict=True)}
    foot = sel.drop_duplicates("run_id")
    span = order["label"].iloc[0] + ("" if len(order) == 1 else f"..{order['label'].iloc[-1]}")
    foot = foot.assign(git_commit=span, machine=[f"{c} cores" for c in foot["cores"]],
                       date=foot["date"].astype(str))
    footer = provenance_line(foot, what=f"{shown}: {n_runs} runs")
    fig, axes = new_figure(len(PANELS), width=PANEL_W * len(PANELS),
                           height=PANEL_H * 1.25, footer=footer)
    colour = {m: f"C{i % 10}" for i, m in enumerate(sorted(sel["machine"].unique()))}
    step = max(1, -(-len(order) // MAX_TICKS))
    ticks = order.iloc[::step]
    for ax, panel in zip(axes, PANELS, strict=True):
        p = sel[(sel["suite"] == panel.suite) & (sel["benchmark"] == panel.benchmark)]
        p = p.sort_values("date", kind="stable")
        # runs of one commit side by side, oldest left
        same = p.groupby(["commit", "dirty"])
        k, n = same.cumcount().to_numpy(), same["run_id"].transform("size").to_numpy()
        spread = np.where(n > 1, 0.3 * (k / np.maximum(n - 1, 1) - 0.5), 0.0)
        p = p.assign(x=[x_of[(c, d)] for c, d in zip(p["commit"], p["dirty"], strict=True)]
                     + spread)
        for machine, g in p[~p["dirty"]].groupby("machine"):  # each commit's best, joined
            best = g.loc[g.groupby("commit")["value"].idxmin()].sort_values("x")
            ax.plot(best["x"], best["value"], "-", lw=0.8, alpha=0.5, color=colour[machine])
        for (machine, dirty), g in p.groupby(["machine", "dirty"]):
            ax.plot(g["x"], g["value"], "o", ms=5, color=colour[machine],
                    markerfacecolor="none" if dirty else colour[machine],
                    label=None if dirty else machine)
        if p.empty:
            ax.text(0.5, 0.5, "not in the history yet", ha="center", va="center",
                    transform=ax.transAxes, color="0.4")
        ax.set_xticks(list(ticks["x"]), list(ticks["label"]), rotation=45, ha="right",
                      fontsize=6)
        ax.set_xlim(-0.6, len(order) - 0.4)
        ax.set_ylim(0, float(p["value"].max()) * 1.15 if len(p) else 1.0)
        ax.set(title=panel.title, ylabel=p["unit"].iloc[0] if len(p) else "ns/DOF",
               xlabel="commit (oldest first)")
    handles = [Line2D([], [], ls="", marker="o", color=c, label=m) for m, c in colour.items()]
    if sel["dirty"].any():
        handles.append(Line2D([], [], ls="", marker="o", color="0.3", markerfacecolor="none",
                              label="uncommitted changes"))
    axes[0].legend(handles=handles, loc="lower left", fontsize=6)
    return _figure(FIG_ID, FAMILY, TITLE, caption, fig)


# --------------------------------------------------------------------------- command line
def followed(df: pd.DataFrame) -> pd.DataFrame:
    """One row per run of the followed suites: its date, commit, machine and the followed
    figures (min); commits in the figure's order."""
    import pandas as pd

    sel = df[(df["stat"] == FOLLOWED_STAT) & df["suite"].isin({p.suite for p in PANELS})]
    rows = []
    for _, g in sel.groupby("run_id", sort=False):
        first = g.iloc[0]
        row = {"date": str(first["date"])[:16],
               "commit": (first["commit"][:12] or "no git") + ("+dirty" if first["dirty"] else ""),
               "suite": first["suite"],
               "machine": first["machine"]}
        for p in PANELS:
            hit = g[(g["suite"] == p.suite) & (g["benchmark"] == p.benchmark)]
            row[p.title] = float(hit["value"].iloc[0]) if len(hit) else float("nan")
        rows.append(row)
    if not rows:
        return pd.DataFrame(rows)
    order = commit_order(sel)
    x_of = {(c[:12] or "no git") + ("+dirty" if d else ""): x
            for c, d, x in zip(order["commit"], order["dirty"], order["x"], strict=True)}
    table = pd.DataFrame(rows)
    return table.sort_values(["commit", "date"], key=lambda col: col.map(x_of)
                             if col.name == "commit" else col, kind="stable")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--history", type=Path, default=HISTORY_FILE,
                    help=f"the history file (default {HISTORY_FILE})")
    sub = ap.add_subparsers(dest="command", required=True)
    a = sub.add_parser("append", help="append the run of pytest-benchmark JSON files")
    a.add_argument("json", nargs="+", type=Path)
    a.add_argument("--suite", help="the suite's name (default: each file's stem)")
    a.add_argument("--repo", type=Path, default=REPO,
                   help="the checkout whose commit ran the benchmarks (default: this one)")
    s = sub.add_parser("show", help="the followed figures, one line per run")
    s.add_argument("--last", type=int, default=0, help="only the last N runs")
    p = sub.add_parser("plot", help="write the report's figure as a PNG")
    p.add_argument("png", type=Path)
    args = ap.parse_args(argv)
    if args.command == "append":
        for path in args.json:
            rec, new = append_json(path, suite=args.suite, history=args.history, repo=args.repo)
            state = (rec["commit"][:12] or "no git") + ("+dirty" if rec["dirty"] else "")
            print(f"history: {path} ({rec['suite']}, {len(rec['benchmarks'])} benchmarks, "
                  f"{state}) " + (f"appended to {args.history}" if new else
                                  f"already in {args.history}, not appended"))
        return 0
    runs, bad = read_runs(args.history)
    if args.command == "show":
        table = followed(to_frame(runs))
        if table.empty:
            print(NO_HISTORY)
            return 0
        if args.last:
            table = table.tail(args.last)
        print(table.to_string(index=False, float_format=lambda v: f"{v:.1f}"))
        if bad:
            print(f"({bad} unreadable line(s) skipped)")
        return 0
    fig = history_figure(args.history)
    if fig.png is None:
        print(fig.not_run)
        return 1
    args.png.parent.mkdir(parents=True, exist_ok=True)
    args.png.write_bytes(fig.png)
    print(f"{args.png}: {fig.title}. {fig.caption}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
