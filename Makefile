# mmstab: every target sets up what it needs from nothing (virtualenv + editable install).
# `make demo` runs the main job on the default problem; `make test` runs the tests.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
MMSTAB := $(VENV)/bin/mmstab
STAMP := $(VENV)/.installed-stamp
# optional extras every set-up installs (the tests use them all)
EXTRAS := dev,peer,view,validate,atlas
PROBLEM ?= problems/ramp.yaml
export MPLBACKEND ?= Agg

.PHONY: setup demo test lint format clean fig5 fig6 figures bench-controller

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet --editable '.[$(EXTRAS)]'
	touch $(STAMP)

setup: $(STAMP)

## the main job on the default problem: the paper's pipeline, every stage and figure
## (workspace V -> stability sweeps -> CMA-ES plan -> tracking on the ramp -> animation)
demo: setup fig3 fig5 fig6 fig7 fig8 plan-reliable tracking animation

## two pytest workers (pytest-xdist; TEST_WORKERS=auto: one per core), a file's tests on one
## worker (its module fixtures built once); the 15 slowest tests listed (docs/testing.md)
TEST_WORKERS ?= 2
test: setup system
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile --durations=15

## system packages the tests need (Debian): chromium for the browser test of `mmstab view`
.PHONY: system
system:
	@command -v chromium >/dev/null 2>&1 || { \
	  if command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
	    echo "make: installing chromium (browser test of mmstab view)"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; \
	  else \
	    echo "make: chromium is missing and cannot be installed here: the browser test will skip"; \
	  fi; }

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

figures: fig3 fig5 fig6 fig7 fig8 plan-reliable tracking animation

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

## planner vs the exhaustive Eq. 6 reference: time per pose, fitness gap -> results/bench/plan.json
## (and other CMA-ES set-ups on the same poses -> results/bench/plan_alternatives.json)
## (and along the rough route, warm-started: its "route" entry, benchmarks/plan_route.py)
## issue 12: the reliable search (within 0.5 % of the exhaustive optimum) on the same lap
.PHONY: plan-reliable
plan-reliable: setup
	$(MMSTAB) fig8 problems/ramp_reliable.yaml -o results/fig8_reliable

## the paper's search (CMA-ES from two starts, the first release's default) on the same lap
.PHONY: plan-paper
plan-paper: setup
	$(MMSTAB) fig8 problems/ramp_paper.yaml -o results/fig8_paper

bench-plan: setup
	$(PY) benchmarks/plan.py problems/ramp_reliable.yaml --alternatives
	$(PY) benchmarks/plan_route.py problems/rough.yaml --rebuild-roadmap

## paper claims vs saved results (run fig6, fig8, tracking first) -> results/fidelity/summary.json
.PHONY: fidelity
fidelity: setup
	$(MMSTAB) fidelity $(PROBLEM)

## issue 25: mmstab's tips / holds / slides against MuJoCo's on a grid of edge cases
## -> results/verdicts/summary.json, verdicts.png (docs/physics.md, "Verdicts against MuJoCo")
.PHONY: verdicts
VERDICTS ?= problems/verdicts.yaml
verdicts: setup
	$(PY) -m mmstab.experiments.verdicts $(VERDICTS)

## issue 25: mmstab's skid-steer model (sliding in turns) against the whole robot in MuJoCo
## on a ramp grid and along rough.yaml's route -> results/skid/summary.json, skid.png, rough.png
## (docs/physics.md, "Sliding in turns")
.PHONY: skid
SKID ?= problems/skid.yaml
skid: setup
	$(PY) -m mmstab.experiments.skid $(SKID)

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
	$(PY) -m pip install --quiet --editable '.[$(EXTRAS),bench]'
	touch $(BENCH_STAMP)

## every benchmark, each JSON in results/bench/ refreshed (12 min here under load; not part of make test)
BENCHES := bench-codegen bench-controller bench-track bench-step-terrain bench-workspace \
	bench-plan bench-terrain bench-drop bench-sizes bench-view bench-atlas bench-roadmap bench-online bench-physics
.PHONY: $(BENCHES)
bench: $(BENCHES)

## µs per step: interpreted vs generated vs pure C vs mink, time split -> results/bench/bench.json
bench-codegen: $(BENCH_STAMP)
	$(PY) benchmarks/bench_codegen.py $(PROBLEM)

## issue 7: the tracking run animated -> results/tracking/animation.gif
.PHONY: animation
animation: setup
	$(MMSTAB) animation $(PROBLEM)

## issue 18: the interactive 3-D viewer of the default run (prints its URL; Ctrl-C stops).
## VIEW_ARGS passes options, e.g. make view VIEW_ARGS="--host 0.0.0.0 --port 8090 --no-browser"
.PHONY: view view-screenshot bench-view
VIEW_RUN ?= results/tracking
view: setup
	@test -f $(VIEW_RUN)/run.npz || $(MAKE) tracking
	$(MMSTAB) view $(PROBLEM) --run $(VIEW_RUN) $(VIEW_ARGS)

## the viewer as headless chromium shows it -> results/view/viewer.png (the README's picture)
view-screenshot: setup
	@test -f $(VIEW_RUN)/run.npz || $(MAKE) tracking
	$(PY) -m mmstab.viz.viewer.snapshot $(PROBLEM) $(VIEW_RUN) results/view/viewer.png

## seconds to the first page: mmstab view vs bare viser vs MeshCat -> results/bench/view.json
## (MeshCat is not a dependency: MESHCAT_PY=/path/to/a/python/with/meshcat adds it)
bench-view: setup
	@test -f $(VIEW_RUN)/run.npz || $(MAKE) tracking
	$(PY) benchmarks/bench_view.py $(PROBLEM) --run $(VIEW_RUN) $(if $(MESHCAT_PY),--meshcat-python $(MESHCAT_PY))

## issue 14 item 5: resting pose vs MuJoCo heightfield drops -> results/terrain/summary.json, validation.png
.PHONY: validate-terrain
VALIDATION ?= problems/validate_terrain_rest.yaml
validate-terrain: setup
	$(PY) benchmarks/validate_terrain.py $(VALIDATION)

## drops per pose: Python loop with early stop vs mujoco.rollout -> results/bench/drop.json
.PHONY: bench-drop
bench-drop: setup
	$(PY) benchmarks/bench_drop.py

## what the local ground in the reference costs the step (docs/controller-terrain.md)
.PHONY: bench-step-terrain
bench-step-terrain: setup
	$(PY) benchmarks/step_terrain.py $(PROBLEM)

## issue 14: uneven terrain: stability maps + 3-D views of the shipped terrains, benchmark
TERRAINS ?= problems/rough.yaml problems/kerb.yaml problems/dem.yaml
.PHONY: terrain bench-terrain
terrain: setup
	for p in $(TERRAINS); do $(MMSTAB) stability-map $$p || exit 1; done

## ms per resting pose, batched vs one by one -> results/bench/terrain.json
bench-terrain: setup
	$(PY) benchmarks/bench_terrain.py $(TERRAINS)

## posture roadmap (issue 24): lattice roadmap vs OMPL PRM* / RRT-Connect -> results/bench/roadmap.json
.PHONY: bench-roadmap
bench-roadmap: $(BENCH_STAMP)
	$(PY) benchmarks/bench_roadmap.py problems/rough.yaml --rebuild

## edges (issue 13): are the size estimates of mmstab/core/sizes.py bounds here? -> results/bench/sizes.json
.PHONY: bench-sizes
bench-sizes: setup
	$(PY) benchmarks/sizes.py $(PROBLEM)
## issue 17: tip-over envelope atlas on Dask (docs/atlas.md) -> results/atlas/; benchmark
.PHONY: atlas bench-atlas
# the atlas wants each cell's best posture: the reliable planner search (docs/planner.md)
ATLAS_PROBLEM ?= problems/ramp_reliable.yaml
atlas: setup
	$(MMSTAB) atlas $(ATLAS_PROBLEM)

bench-atlas: setup
	$(PY) benchmarks/atlas.py $(ATLAS_PROBLEM)

## issue 16: payload, flippers, lap speed, robot variants (docs/levers.md) -> results/levers/
.PHONY: levers
levers: setup
	$(MMSTAB) levers problems/levers.yaml

## the atlas on generated rough ground, three terrain seeds x two payloads -> results/atlas_rough/
.PHONY: atlas-rough
atlas-rough: setup
	$(MMSTAB) atlas problems/rough_atlas.yaml -o results/atlas_rough

## issue 15: plan and track along a route over rough ground (docs/routes.md) -> results/rough/,
## results/kerb/: the plan (plan/), the tracking run, its figures and the animation
.PHONY: rough kerb
rough: setup
	$(MMSTAB) plan problems/rough.yaml -o results/rough/plan --allow-unstable --allow-sliding
	$(MMSTAB) track problems/rough.yaml -o results/rough --allow-unstable --allow-sliding
	$(MMSTAB) animation problems/rough.yaml -o results/rough

## issue 25 (docs/physics.md): the ramp lap and the shipped routes in MuJoCo with the controller
## in the loop -> results/physics/ (the lap), results/physics/<route>_<arm>/. rough.yaml slides
## where mmstab says so (--allow-sliding); the kerb's planned arm keeps off the ground through the
## body's rocking (planner.attitude_margin; without it the wrist grazed the kerb's top, exit 5),
## make still goes on ("-") if it does not; docs/physics.md.
.PHONY: physics bench-physics
physics: setup
	$(MMSTAB) simulate problems/ramp.yaml -o results/physics
	$(MMSTAB) simulate problems/kerb.yaml -o results/physics/kerb_stowed --arm stowed
	$(MMSTAB) simulate problems/rough.yaml -o results/physics/rough_stowed --arm stowed --allow-sliding
	-$(MMSTAB) simulate problems/kerb.yaml -o results/physics/kerb_planned
	$(MMSTAB) simulate problems/rough.yaml -o results/physics/rough_planned --allow-sliding
	$(MMSTAB) simulate problems/dem.yaml -o results/physics/dem_planned --allow-sliding

## real-time factor of the MuJoCo model and the closed loop (one core) -> results/bench/physics.json
bench-physics: setup
	$(PY) benchmarks/bench_physics.py

## issue 26 (docs/online.md): a generated robot recording of the rough route, followed online
.PHONY: online bench-online
online: setup
	$(MMSTAB) record problems/rough.yaml -o results/online/rough.mcap
	$(MMSTAB) follow problems/rough.yaml --bag results/online/rough.mcap -o results/online --allow-sliding
	$(PY) -m mmstab.viz.viewer.snapshot problems/rough.yaml results/online results/online/viewer.png 0.45 3.0

## latency per map of mmstab follow (one core) beside the offline planner -> results/bench/online.json
bench-online: setup
	$(PY) benchmarks/bench_online.py problems/rough.yaml --recording results/online/rough.mcap

kerb: setup
	$(MMSTAB) plan problems/kerb.yaml -o results/kerb/plan --allow-unstable --allow-sliding
	$(MMSTAB) track problems/kerb.yaml -o results/kerb --allow-unstable --allow-sliding
	$(MMSTAB) animation problems/kerb.yaml -o results/kerb

## issue 24: 20 seeded random routes over 20 seeded random heightmaps, planned on the posture
## roadmap and tracked (docs/routes.md, "Random routes") -> results/random_routes/summary.json
.PHONY: random-routes
## (PAIRS=60: pairs 0-59, the 40 beyond the issue's drawn by the same generator)
PAIRS ?= 20
random-routes: setup
	MMSTAB_RANDOM_ROUTES=1 MMSTAB_RANDOM_PAIRS=$(PAIRS) $(PY) -m pytest -q -s tests/runs/test_random_routes.py -k full_set
