"""The accuracy gates (gates.toml, harness/gates.py): the file is well-formed and consistent with
the tests it mirrors, the runner reports FAIL / SKIP rows instead of crashing, exit codes, and the
gates have teeth (a broken core fails them)."""

from __future__ import annotations

import math
import os
import re
import time

import pytest
import test_engines_agreement

import redysim
from redysim import references
from redysim.harness import gates

GATES = gates.load_gates()
BY_NAME = {g.name: g for g in GATES}
CHEAP = ["table9.*", "table11.*", "e0"]  # gates that run in about a second


def test_every_gate_is_complete_and_its_reason_is_one_sentence():
    assert len(GATES) >= 10
    for g in GATES:
        assert g.compare in gates.COMPARISONS and g.measure in gates.MEASURES
        assert g.reason.endswith("."), g.name
        assert not re.search(r"\.\s+[A-Z]", g.reason), f"{g.name}: more than one sentence"


def test_the_required_gates_are_there():
    for name in ("table9.gim", "table9.qdd", "table11.cond2", "e0", "rge-a.true-error",
                 "energy.drift", "work-precision"):
        assert name in BY_NAME
    assert set(BY_NAME["e0"].params["cases"]) == {"RE-U125-L1", "RE-U750-L6", "RE-U3750-L30"}
    assert BY_NAME["work-precision"].params["integrators"] == ["ode45", "dop853"]


def test_engine_gates_cover_every_engine_with_the_tests_tolerance():
    """One gate per engine, its threshold the tolerance of tests/test_engines_agreement.py."""
    engine_gates = {g.params["engine"]: g for g in GATES
                    if g.measure == "engine_agreement" and "stages" not in g.params}
    assert set(engine_gates) == set(references.ENGINES)
    for name, g in engine_gates.items():
        assert g.compare == "<=" and g.threshold == test_engines_agreement.TOLERANCE[name]


def test_the_known_engine_defect_is_gated_where_the_tests_xfail_it():
    defect = BY_NAME["engine.pinocchio-aba.known-defect"]
    excluded = {tuple(x) for x in BY_NAME["engine.pinocchio-aba"].params["exclude"]}
    assert excluded == {(c, s) for c in defect.params["chains"] for s in defect.params["stages"]}
    assert {(e, f"{j}{n}", s) for e, j, n, _, s in test_engines_agreement.PIN_UNIVERSAL_DEFECT} \
        == {("pinocchio-aba", c, s) for c, s in excluded}


@pytest.mark.parametrize("compare, threshold, value, ok", [
    ("<=", 1.0, 1.0, True), ("<=", 1.0, 1.5, False), ("<=", 1.0, math.nan, False),
    ("<=", 1.0, -math.inf, False), (">=", 1.0, 2.0, True), (">=", 1.0, math.inf, False),
    ("==", 0.0, 0.0, True), ("==", 0.0, 1e-300, False), ("==", 0.0, math.nan, False),
    ("within", (1.0, 2.0), 1.5, True), ("within", (1.0, 2.0), 2.5, False),
    ("within", (1.0, 2.0), math.nan, False),
])
def test_comparisons(compare, threshold, value, ok):
    g = gates.Gate("g", "q", "table9", compare, threshold, "r.")
    assert g.check(value) is ok


GOOD_GATE = '''[[gate]]
name = "g"
quantity = "q"
measure = "table9"
params = { item = "cond2" }
compare = "within"
threshold = [309.225, 309.235]
reason = "Because."
'''


@pytest.mark.parametrize("old, new, field", [
    ('measure = "table9"', 'measure = "nope"', "gate 'g'.measure = 'nope'"),
    ('compare = "within"', 'compare = "<"', "gate 'g'.compare = '<'"),
    ("threshold = [309.225, 309.235]", "threshold = [2.0, 1.0]", "gate 'g'.threshold"),
    ("threshold = [309.225, 309.235]", 'threshold = "small"', "gate 'g'.threshold"),
    ('reason = "Because."\n', "", "gate[0].reason: missing field"),
    ('reason = "Because."', 'reason = ""', "gate 'g'.reason"),
    ('name = "g"', 'name = "g"\ncolour = "red"', "gate[0].colour = 'red': unknown field"),
    ("params = { item = \"cond2\" }", "params = 3", "gate 'g'.params = 3"),
])
def test_a_malformed_gates_file_is_named(tmp_path, capsys, old, new, field):
    path = tmp_path / "gates.toml"
    path.write_text(GOOD_GATE.replace(old, new))
    assert gates.main(["--gates", str(path)]) == gates.EXIT_USAGE
    err = capsys.readouterr().err
    assert str(path) in err and field in err, err


def test_duplicate_gate_names_are_refused(tmp_path):
    path = tmp_path / "gates.toml"
    path.write_text(GOOD_GATE + "\n" + GOOD_GATE)
    with pytest.raises(gates.GatesError, match="duplicate gate name"):
        gates.load_gates(path)


def test_only_with_an_unknown_name_is_a_usage_error(capsys):
    assert gates.main(["--only", "no-such-gate"]) == gates.EXIT_USAGE
    assert "no such gate; known: table9.gim" in capsys.readouterr().err


def test_the_cheap_gates_pass(capsys):
    argv = [x for pattern in CHEAP for x in ("--only", pattern)]
    assert gates.main(argv) == gates.EXIT_OK
    out = capsys.readouterr().out
    assert "6 gates, 14 rows: 14 pass, 0 FAIL, 0 SKIP" in out
    assert "table11.cond2/R100" in out and "e0/RE-U3750-L30" in out


def test_a_measure_that_raises_is_a_fail_row_not_a_crash(monkeypatch, capsys):
    def broken(gate):
        raise FloatingPointError("kernel overflow")

    monkeypatch.setitem(gates.MEASURES, "table9", broken)
    assert gates.main(["--only", "table9.gim"]) == gates.EXIT_FAILED
    out = capsys.readouterr().out
    assert re.search(r"table9\.gim\s+-\s+== 0\s+FAIL\s+error: FloatingPointError", out), out
    assert "0 pass, 1 FAIL" in out and "FAILED: table9.gim" in out
    (row,) = gates.run_gate(BY_NAME["table9.gim"])
    assert row.where == "error: FloatingPointError: kernel overflow"


def test_a_missing_engine_is_a_printed_skip_not_a_pass(monkeypatch, capsys):
    cls = references.get("dart")
    monkeypatch.setattr(cls, "available", classmethod(lambda c: False))
    assert gates.main(["--only", "engine.dart"]) == gates.EXIT_OK
    out = capsys.readouterr().out
    assert re.search(r"engine\.dart\s+-\s+<= 1e-11\s+SKIP\s+not installed", out), out
    assert "0 pass, 0 FAIL, 1 SKIP" in out and "SKIPPED (not measured, not passed)" in out
    assert gates.main(["--only", "engine.dart", "--strict"]) == gates.EXIT_FAILED


def test_a_broken_core_fails_the_gates(monkeypatch, capsys):
    """The gates have teeth: phi with its sign flipped fails Table 9 (phi, and qdd by GE-N)."""
    real = redysim.phi
    monkeypatch.setattr(redysim, "phi", lambda *a, **kw: -real(*a, **kw))
    assert gates.main(["--only", "table9.phi"]) == gates.EXIT_FAILED
    assert re.search(r"table9\.phi\s+\S+\s+== 0\s+FAIL", capsys.readouterr().out)


@pytest.mark.engine
def test_an_engine_gate_measures_all_stages(capsys):
    if not references.get("dart").available():
        pytest.skip("dart not installed")
    rows = gates.run_gate(BY_NAME["engine.dart"])
    assert [r.gate for r in rows] == ["engine.dart/gim", "engine.dart/phi", "engine.dart/qdd"]
    assert all(r.result == gates.PASS for r in rows)


def test_a_gate_past_its_time_limit_is_a_fail_row_and_the_next_gate_runs(monkeypatch, capsys):
    def crawl(gate):  # a broken core can make an integration crawl: the gate must give up
        while True:
            sum(range(10_000))  # CPU time: the limit counts it, whatever the machine's load

    monkeypatch.setitem(gates.MEASURES, "table9", crawl)
    (row,) = gates.run_gate(BY_NAME["table9.gim"], time_limit_s=0.3)
    assert row.result == gates.FAIL
    assert row.where == ("error: GateTimeout: time limit: still measuring after 0.3 s of CPU "
                         "time")
    # the timers are disarmed afterwards: a following gate runs to its end
    nxt, *_ = gates.run_gate(BY_NAME["e0"], time_limit_s=30, wall_guard_s=30)
    time.sleep(0.5)
    assert nxt.result == gates.PASS


def test_a_gate_that_waits_is_given_up_by_the_wall_guard_as_a_skip(monkeypatch):
    """Waiting uses no CPU time: the CPU limit never strikes, and the wall-clock guard (the
    user's patience) gives the gate up as not measured, never as a FAIL decided by load."""
    def wait(gate):
        while True:
            time.sleep(0.01)

    monkeypatch.setitem(gates.MEASURES, "table9", wait)
    (row,) = gates.run_gate(BY_NAME["table9.gim"], time_limit_s=30, wall_guard_s=0.3)
    assert row.result == gates.SKIP
    assert row.where.startswith("given up after 0.3 s of wall time (the wall-clock guard: your "
                                "patience, not a measurement")


def test_one_gates_run_computes_each_reference_once(monkeypatch):
    seen = []
    with gates._fresh_results_dir() as outer:
        with gates._fresh_results_dir() as inner:
            seen.append(os.environ[gates.RESULTS_ENV])
        assert inner == outer and seen == [str(outer)]
    assert not outer.exists()


def test_the_list_stops_quietly_when_its_reader_goes_away():
    """``python -m redysim.harness.gates --list | head -1`` raised BrokenPipeError at the first
    line head did not read."""
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "redysim.harness.gates", "--list"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None and proc.stderr is not None
    first = proc.stdout.readline()
    proc.stdout.close()  # the reader goes away after one line, as head -1 does
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 0, err
    assert first.strip() and "Traceback" not in err and "BrokenPipe" not in err, err
