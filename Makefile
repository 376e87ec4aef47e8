# mmstab: every target sets up what it needs from nothing (virtualenv + editable install).
# `make demo` runs the main job on the default problem; `make test` runs the tests.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
MMSTAB := $(VENV)/bin/mmstab
STAMP := $(VENV)/.installed-stamp
PROBLEM ?= problems/ramp.yaml
export MPLBACKEND ?= Agg

.PHONY: setup demo test lint format clean fig5 fig6 figures bench-controller

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet --editable '.[dev,peer,atlas]'
	touch $(STAMP)

setup: $(STAMP)

## the main job on the default problem: the paper's pipeline, every stage and figure
## (workspace V -> stability sweeps -> CMA-ES plan -> tracking on the ramp -> animation)
demo: setup fig3 fig5 fig6 fig7 fig8 tracking animation

test: setup
	$(PY) -m pytest -q

lint: setup
	$(VENV)/bin/ruff check mmstab tests benchmarks
	$(VENV)/bin/ruff format --check mmstab tests benchmarks
	$(VENV)/bin/mypy mmstab

format: setup
	$(VENV)/bin/ruff format mmstab tests benchmarks
	$(VENV)/bin/ruff check --fix mmstab tests benchmarks

## paper experiments: one target each, results in results/<name>/
fig5: setup
	$(MMSTAB) fig5 $(PROBLEM)

fig6: setup
	$(MMSTAB) fig6 $(PROBLEM)

figures: fig3 fig5 fig6 fig7 fig8 tracking animation

## benchmark (not a test): µs per controller step per QP plugin -> results/bench/controller.json
bench-controller: setup
	$(PY) benchmarks/bench_controller.py $(PROBLEM)

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache .mypy_cache *.egg-info

## arm-CoM workspace V (paper Section II-B): cached build, Fig. 3, build benchmark
.PHONY: workspace fig3 bench-workspace
workspace: setup
	$(MMSTAB) workspace $(PROBLEM)

fig3: setup
	$(MMSTAB) fig3 $(PROBLEM)

bench-workspace: setup
	$(PY) benchmarks/workspace.py $(PROBLEM)

## stability planner (paper Section II-D): CMA-ES per base pose, Fig. 7 and Fig. 8
.PHONY: plan fig7 fig8 bench-plan
plan: setup
	$(MMSTAB) plan $(PROBLEM)

fig7: setup
	$(MMSTAB) fig7 $(PROBLEM)

fig8: setup
	$(MMSTAB) fig8 $(PROBLEM)

bench-plan: setup
	$(PY) benchmarks/plan.py $(PROBLEM)

## trajectory tracking (paper Section II-E, Fig. 9-12): one run, four figures; benchmark
.PHONY: tracking fig9 fig10 fig11 fig12 bench-track
tracking: setup
	$(MMSTAB) track $(PROBLEM)

fig9 fig10 fig11 fig12: tracking

bench-track: setup
	$(PY) benchmarks/bench_tracking.py $(PROBLEM)

## embedded controller (issue 6): the step as generated C, the standalone C closed loop, benchmarks
.PHONY: codegen embedded bench
codegen: setup
	$(MMSTAB) codegen $(PROBLEM)

embedded: setup
	$(MMSTAB) codegen $(PROBLEM) -o results/codegen/embedded --example
	results/codegen/embedded/mmstab_loop results/codegen/embedded/run.bin

BENCH_STAMP := $(VENV)/.bench-stamp
$(BENCH_STAMP): $(STAMP)
	$(PY) -m pip install --quiet --editable '.[dev,peer,bench]'
	touch $(BENCH_STAMP)

## µs per step: interpreted vs generated vs pure C vs mink -> results/bench/bench.json
bench: $(BENCH_STAMP)
	$(PY) benchmarks/bench_codegen.py $(PROBLEM)

## issue 7: the tracking run animated -> results/tracking/animation.gif
.PHONY: animation
animation: setup
	$(MMSTAB) animation $(PROBLEM)

## issue 17: tip-over envelope atlas on Dask (docs/atlas.md) -> results/atlas/; benchmark
.PHONY: atlas bench-atlas
atlas: setup
	$(MMSTAB) atlas $(PROBLEM)

bench-atlas: setup
	$(PY) benchmarks/atlas.py $(PROBLEM)
