# Two commands for a new user (see README):
#   make run    set up .venv (package + ROS 2 Jazzy wheels) and run the default scene
#   make test   set up .venv and run the whole test suite
# Both are idempotent: the venv is rebuilt only when setup.py or requirements/ change.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
ARGS   ?=
SHELL  := /bin/bash
.SHELLFLAGS := -o pipefail -ec
# this machine's pip config names local indexes that may not exist: drop that noise, keep errors
QUIET  := 2>&1 | { grep -v "is ignored: it is neither" || true; }

.PHONY: run test fuzz fuzz-random stability bench docs clean venv

venv: $(STAMP)

$(STAMP): setup.py requirements/ros.txt requirements/dev.txt
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip $(QUIET)
	$(PY) -m pip install --quiet -e '.[test,plot]' -r requirements/dev.txt $(QUIET)
	$(PY) -c "import contact_sim, rclpy"
	$(PY) -m contact_sim.warmup   # compile the kernels once (numba's cache), so no test or first run stalls on it
	$(PY) -m msg_adapters.state_rows   # and the node's (no ROS import: it runs without the ROS wheels too)
	touch $(STAMP)

run: $(STAMP)
	$(VENV)/bin/contact-sim run $(ARGS)

# the whole suite, then (with no ARGS) the quick exact-answer tests once more through the plain
# Python path of every compiled kernel (NUMBA_DISABLE_JIT=1), so that path stays correct too
test: $(STAMP)
	$(PY) -m pytest $(ARGS)
	@if [ -z "$(ARGS)" ]; then echo "exact-answer tests without the JIT:"; \
	  NUMBA_DISABLE_JIT=1 $(PY) -m pytest -q -m exact -p no:cacheprovider; fi

# the ten-second stability scenes (test/test_stability.py, marker stability; prints HARD lines)
stability: $(STAMP)
	$(PY) -m pytest -q -s -m stability -p no:cacheprovider $(ARGS)

# the long property-based profile (test/test_properties.py, marker fuzz): CI runs it after make test
fuzz: $(STAMP)
	$(PY) -m pytest -q -m fuzz -p no:cacheprovider $(ARGS)

# the long profile with fresh random draws: N examples per property (make fuzz-random N=2000 [SEED=s]
# [JOBS=j]); prints the seed and saves every failing example as a case in fuzz-found/
N ?= 1000
fuzz-random: $(STAMP)
	$(PY) test/fuzz_random.py --examples $(N) $(if $(SEED),--seed $(SEED)) $(if $(JOBS),--jobs $(JOBS)) $(ARGS)

# every benchmark in bench/ (tables on stdout, CSV/PNG in bench/results/; pybullet and MuJoCo are
# the references), the hard cases' measured figures, then the measured results in docs/benchmarks.md
bench: $(STAMP)
	$(PY) -m pip install --quiet pybullet mujoco $(QUIET)
	$(PY) bench/bench_detect.py
	$(PY) bench/bench_response.py
	$(PY) bench/step_anatomy.py
	$(PY) bench/bench_default.py
	$(PY) bench/bench_accuracy.py
	$(PY) bench/bench_node.py
	$(PY) bench/bench_mesh_mesh.py
	$(PY) bench/bench_robot.py
	$(PY) bench/bench_panda.py
	$(PY) bench/bench_node.py --panda
	$(PY) bench/bench_collide.py
	$(PY) bench/bench_study.py
	$(PY) -m pytest -q -m "hard or stability" -s -p no:cacheprovider | grep -o "HARD .*" | sed "s/^HARD //" > bench/results/hard_cases.txt
	$(PY) bench/report.py

# the documentation site (mkdocs.yml, docs/): the docs tooling (setup.py's "docs" extra) into the venv,
# then a strict build into site/: a broken link or anchor, a missing page or any warning fails; the API
# reference and the node's parameter table are generated from the code (docs/hooks/)
docs: $(STAMP)
	$(PY) -m pip install --quiet -e '.[docs]' $(QUIET)
	NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs build --strict --site-dir site

clean:
	rm -rf $(VENV) build install log .pytest_cache site
