# Set-up and main jobs. Python 3.11, make and a C compiler are all they need;
# everything else is installed into .venv on first use.
PYTHON ?= python3
CC ?= cc
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
ENGINE := $(wildcard src/vsj/engine/c/*.c src/vsj/engine/c/*.h) src/vsj/_core.c

.PHONY: install reproduce figures test bench sanitize portable clean

install: $(STAMP)

# the engine is C: (re)installing compiles it, so the stamp follows its sources.
# The bytecode is compiled after the install, on every core (pip compiles one file at a
# time), so that no command compiles modules as it starts, even where
# PYTHONDONTWRITEBYTECODE keeps Python from saving what it compiles. Left out: the
# libraries' own test suites and the installers (pip, setuptools), which neither vsj
# nor its tests import: a third of the source in .venv, and of the install's time.
NO_BYTECODE := site-packages/(.+/)?tests?/|site-packages/(pip|setuptools|pkg_resources)/
$(STAMP): pyproject.toml setup.py $(ENGINE)
	test -d $(VENV) || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --no-compile -e '.[test]'
	$(BIN)/python -m compileall -q -j 0 -x '$(NO_BYTECODE)' $(VENV)/lib src
	touch $(STAMP)

reproduce: $(STAMP)
	$(BIN)/vsj reproduce --out reproduction

# the figures README.md shows, each copied from what a vsj command writes (the explorer's
# screenshot from vsj explore in headless Chromium), so that none is drawn by hand (tests/test_readme.py checks that this recipe writes every one of them)
figures: $(STAMP)
	rm -rf build/figures
	$(BIN)/vsj reproduce --only fig-4.13 fig-4.15 --out build/figures/reproduction
	$(BIN)/vsj msl friction --out build/figures/msl
	cp build/figures/reproduction/fig-4.13.png docs/fig-4.13.png
	cp build/figures/reproduction/fig-4.15.png docs/fig-4.15.png
	cp build/figures/msl/msl-friction.png docs/msl-friction.png
	$(BIN)/python tools/explorer_screenshot.py build/figures/explorer.png
	cp build/figures/explorer.png docs/explorer.png

# one worker per core, a test file to a worker, the costliest files first (in the order
# tests/conftest.py collects them). The workers already fill the cores, so OpenBLAS runs
# on one thread in each: its threads would only wait on a busy core for the other
# worker, spinning (CPU time taken from that worker, no wall time gained)
test: $(STAMP)
	OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -q -n auto --dist loadfile --no-loadscope-reorder

# the engine under AddressSanitizer and UndefinedBehaviorSanitizer (also run by make test)
sanitize: $(STAMP)
	$(BIN)/python tests/sanitize.py build/sanitize

# the suite under other floating-point configurations: -O0 without contraction, fused
# multiply-add, -O3 -march=native, clang, OpenBLAS's oldest x86-64 kernel (tools/portable.py)
portable: $(STAMP)
	$(BIN)/python tools/portable.py

# the sweep benchmark's Monte Carlo is 100 000 runs (issue 22); make bench runs 3000 of
# them so that it finishes in minutes: VSJ_SWEEP_RUNS=100000 make bench for the full study
bench: $(STAMP)
	$(BIN)/python benchmarks/run.py
	$(BIN)/python benchmarks/friction_laws.py
	$(BIN)/python benchmarks/step_cost.py
	$(BIN)/python benchmarks/control.py
	$(BIN)/python benchmarks/msl.py
	$(BIN)/python benchmarks/identify_wrist.py
	$(BIN)/python benchmarks/sweep.py $${VSJ_SWEEP_RUNS:-3000}
	$(BIN)/python benchmarks/simulate_cli.py
	$(BIN)/python benchmarks/long_run.py
	$(BIN)/python benchmarks/fmu.py
	$(BIN)/python benchmarks/explore.py

clean:
	rm -rf $(VENV) reproduction out build src/vsj.egg-info src/vsj/*.so src/vsj/engine/*.so
