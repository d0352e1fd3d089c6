# redysim: the front door. `make reproduce` and `make test` set everything up on a fresh machine.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
EXTRAS := test,harness,engines,models
STAMP  := $(VENV)/.installed
export PYTHONDONTWRITEBYTECODE := 1

.PHONY: help venv test test-fast test-rest reproduce bench bench-core bench-engines lint constraints clean

help:
	@echo "make reproduce     venv + install + quick reproduction (~9-10 min on 2 quiet cores, ~12-15 beside a busy process): runs, then reports/out/report.{html,pdf}"
	@echo "make reproduce-full every table to the paper's horizons (hours; resumable), then the report"
	@echo "                   (DASK=tcp://host:8786 with either: every sweep's runs on that Dask cluster)"
	@echo "make table1 .. table11, tableA2   only what that table needs, then the report"
	@echo "make test          venv + install + the test suite (test-fast: ruff, mypy and the fast tests; test-rest)"
	@echo "make gates         accuracy gates of harness/gates.toml: a table, exit 1 if any fails"
	@echo "make bench         benchmarks of the core (pytest-benchmark; JIT compile timed apart; default call vs ws=; batches beside a busy process;"
	@echo "                   whether an adaptive rope pays: benchmarks/adaptive_rope.py, ~2 min),"
	@echo "                   appended to the performance history benchmarks/history/bench.jsonl (commit it)"
	@echo "make bench-engines qdd per call, core vs every reference engine, 20..100,000 DOF (history too);"
	@echo "                   the latency/throughput ladder: xArm7, Talos, a 250-DOF rope, from a call to a"
	@echo "                   simulated second at 1e-6 m (benchmarks/ladder.py, ~30 min: each engine's runs)"
	@echo "make lint          ruff"

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# Reinstall when the project's dependency declarations change.
$(STAMP): pyproject.toml requirements/constraints.txt | $(BIN)/python
	$(BIN)/python -m pip install --quiet -c requirements/constraints.txt -e ".[$(EXTRAS)]"
	@touch $@

venv: $(STAMP)

# Two stages, the cheap checks first: lint and the fast tests fail in a minute or two; then
# the slow and engine tests. Together they are the whole suite.
test: test-fast test-rest

test-fast: $(STAMP)
	$(BIN)/ruff check --no-cache .
	$(BIN)/mypy
	$(BIN)/python -m pytest -m "not slow and not engine"

test-rest: $(STAMP)
	$(BIN)/python -m pytest -m "slow or engine"

.PHONY: gates
gates: $(STAMP)
	$(BIN)/python -m redysim.harness.gates

# The paper's tables, one target each (reports/reproduce.py --table N).
PAPER_TABLES := 1 2 3 4 5 6 7 8 9 10 11 A2
TABLE_TARGETS := $(addprefix table,$(PAPER_TABLES))
.PHONY: reproduce-full $(TABLE_TARGETS)

# DASK=tcp://host:8786 (or local): every sweep's runs on that Dask cluster (docs/guide.md)
DASK ?=
DASK_FLAG := $(if $(DASK),--dask $(DASK),)

reproduce: $(STAMP)
	$(BIN)/python -m redysim.reports.reproduce $(DASK_FLAG)

reproduce-full: $(STAMP)
	$(BIN)/python -m redysim.reports.reproduce --full $(DASK_FLAG)

$(TABLE_TARGETS): table%: $(STAMP)
	$(BIN)/python -m redysim.reports.reproduce --table $* $(DASK_FLAG)

# Every benchmark run appends its figures, commit, machine and date to the performance history
# (benchmarks/history/bench.jsonl, tracked: commit it; redysim.reports.history), which the report
# plots across commits. BENCH_ARGS goes to pytest: a shorter run, e.g.
# make bench-core BENCH_ARGS="--benchmark-max-time=0.2 -k 'rge_a_u_chain or batch'"
BENCH_ARGS ?=

bench: bench-core

bench-core: $(STAMP)
	@mkdir -p results/bench
	$(BIN)/python benchmarks/jit_times.py
	$(BIN)/python benchmarks/float32_speed.py
	$(BIN)/python benchmarks/adaptive_rope.py
	$(BIN)/python benchmarks/step_cost.py
	$(BIN)/python benchmarks/default_path.py
	$(BIN)/python benchmarks/busy_batch.py
	$(BIN)/python -m pytest benchmarks/test_bench_core.py --benchmark-only --benchmark-enable \
		--benchmark-columns=min,median,mean,rounds --benchmark-sort=name \
		--benchmark-json=results/bench/core.json $(BENCH_ARGS)
	$(BIN)/python -m redysim.reports.history append results/bench/core.json

bench-engines: $(STAMP)
	@mkdir -p results/bench
	$(BIN)/python -m pytest benchmarks/test_bench_engines.py --benchmark-only --benchmark-enable \
		--benchmark-json=results/bench/engines.json $(BENCH_ARGS)
	$(BIN)/python -m redysim.references.report_bench results/bench/engines.json
	$(BIN)/python benchmarks/ladder.py
	$(BIN)/python -m redysim.reports.history append results/bench/engines.json

lint: $(STAMP)
	$(BIN)/ruff check --no-cache .

constraints: $(BIN)/python
	{ echo "# Exact versions the project was tested with (pip constraints: install with -c)."; \
	  echo "# Regenerate with 'make constraints' after an upgrade, then run 'make test'."; \
	  $(BIN)/python -m pip freeze | grep -v -i "^-e\|^redysim\|^#"; } > requirements/constraints.txt

clean:
	rm -rf $(VENV) results .pytest_cache .benchmarks
