# Set-up and main jobs. Python 3.11, make and a C compiler are all they need;
# everything else is installed into .venv on first use.
PYTHON ?= python3
CC ?= cc
VENV := .venv
BIN := $(VENV)/bin
# uv installs into .venv: it resolves, downloads and installs on every core, where
# pip takes most of a fresh install's time over one package after the other.
UV := $(BIN)/uv pip install --quiet --python $(BIN)/python
STAMP := $(VENV)/.installed
TEST_STAMP := $(VENV)/.test-installed
ENGINE := $(wildcard src/vsj/engine/c/*.c src/vsj/engine/c/*.h) src/vsj/_core.c

.PHONY: install reproduce figures test explore-browser docs docs-browser bench sanitize portable clean

install: $(TEST_STAMP)

# vsj and what it runs on ($(STAMP)), then the test suite's extras ($(TEST_STAMP):
# pytest, FMPy, Bokeh, Selenium, ...), which make reproduce does without.
# The engine is C: (re)installing compiles it, so the stamp follows its sources, and
# vsj is rebuilt on every install (uv would keep a build whose pyproject.toml and
# setup.py did not change). The bytecode is compiled after each install, on every core,
# so that no command compiles modules as it starts, even where PYTHONDONTWRITEBYTECODE
# keeps Python from saving what it compiles. Left out: the libraries' own test suites
# and the installers (pip, setuptools), which neither vsj nor its tests import: a third
# of the source in .venv, and of the compile's time.
NO_BYTECODE := site-packages/(.+/)?tests?/|site-packages/(pip|setuptools|pkg_resources)/
$(STAMP): pyproject.toml setup.py $(ENGINE) | $(BIN)/uv
	$(UV) --reinstall-package vsj -e .
	$(BIN)/python -m compileall -q -j 0 -x '$(NO_BYTECODE)' $(VENV)/lib src
	touch $(STAMP)

# .venv without pip (installing pip into it is most of python -m venv's time; an
# existing .venv is kept as it is), and uv into it by the pip of $(PYTHON); where
# $(PYTHON) has no pip, or one older than 22.3 (no --python), by the pip that ensurepip
# puts into .venv
$(BIN)/uv:
	test -x $(BIN)/python || $(PYTHON) -m venv --without-pip $(VENV)
	$(PYTHON) -m pip --python $(BIN)/python install --quiet 'uv>=0.4' || \
	    { $(BIN)/python -m ensurepip --default-pip >/dev/null && \
	      $(BIN)/python -m pip install --quiet 'uv>=0.4'; }

# the test extra of pyproject.toml (with vsj's own requirements, installed already);
# compileall compiles what is new and passes over what it compiled before
$(TEST_STAMP): $(STAMP)
	$(UV) -r pyproject.toml --extra test
	$(BIN)/python -m compileall -q -j 0 -x '$(NO_BYTECODE)' $(VENV)/lib
	touch $(TEST_STAMP)

reproduce: $(STAMP)
	$(BIN)/vsj reproduce --out reproduction

# the figures README.md shows: the README's own Python snippet, run, and the explorer's
# screenshot from vsj explore in headless Chromium (tests/test_readme.py checks that this
# recipe writes every figure the README shows)
figures: $(TEST_STAMP)
	rm -rf build/figures
	$(BIN)/python tools/readme_figure.py build/figures/readme
	cp build/figures/readme/quickstart.png docs/quickstart.png
	$(BIN)/python tools/explorer_screenshot.py build/figures/explorer.png
	cp build/figures/explorer.png docs/explorer.png
	cp build/figures/explorer-energy.png docs/explorer-energy.png

# one worker per core, a test file to a worker, the costliest files first (in the order
# tests/conftest.py collects them). The workers already fill the cores, so OpenBLAS runs
# on one thread in each: its threads would only wait on a busy core for the other
# worker, spinning (CPU time taken from that worker, no wall time gained)
test: $(TEST_STAMP)
	OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -q -n auto --dist loadfile --no-loadscope-reorder

# the documentation site, into docs/_build/html: the docs extra of pyproject.toml
# installed into .venv (its requirements only: vsj itself is installed already), then
# a full build with warnings as errors, every gallery example run afresh, then an
# offline check of every internal link and anchor and of the references' coverage
DOCS_STAMP := $(VENV)/.docs-installed
$(DOCS_STAMP): $(TEST_STAMP) pyproject.toml
	$(UV) -r pyproject.toml --extra docs
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	rm -rf docs/_build docs/reference/generated docs/getting-started/examples docs/user-guide/examples docs/sg_execution_times.rst
	MPLBACKEND=Agg OPENBLAS_NUM_THREADS=1 $(BIN)/sphinx-build -W --keep-going -q -b html docs docs/_build/html
	$(BIN)/python tools/check_site.py docs/_build/html

# the site that make docs built, in headless Chromium (Debian's chromium and
# chromedriver): no console errors, the equations typeset, search finds "stiction";
# screenshots of the home page and an executed example into build/docs-browser
docs-browser: $(DOCS_STAMP)
	$(BIN)/python tools/browser_check.py docs/_build/html --screenshots build/docs-browser

# vsj explore in headless Chromium (Debian's chromium and chromedriver, driven by
# Selenium): a session as a user would go, checked against vsj simulate; a screenshot
# into build/explore. Outside make test, which needs no browser; .ci/run calls it
explore-browser: $(TEST_STAMP)
	$(BIN)/python -m pytest -q -p no:cacheprovider tests/browser_explorer.py

# the engine under AddressSanitizer and UndefinedBehaviorSanitizer: the job of
# tests/sanitize.py (an instrumented build, every regression scenario, batches, the step
# function, the C example, the FMU's C layer through FMPy) and the checks of its output.
# Outside make test (the suite's longest single job); .ci/run calls it
sanitize: $(TEST_STAMP)
	$(BIN)/python -m pytest -q -p no:cacheprovider tests/sanitizers_check.py

# the suite under other floating-point configurations: -O0 without contraction, fused
# multiply-add, -O3 -march=native, clang, OpenBLAS's oldest x86-64 kernel (tools/portable.py)
portable: $(TEST_STAMP)
	$(BIN)/python tools/portable.py

# the sweep benchmark's Monte Carlo is 100 000 runs (issue 22); make bench runs 6000 of
# them, in three blocks of 2000 (long enough to tell a sweep's cost per run from its fixed
# cost through this VM's drift), so that it finishes in minutes: VSJ_SWEEP_RUNS=100000
# make bench for the full study
bench: $(TEST_STAMP)
	$(BIN)/python benchmarks/run.py
	$(BIN)/python benchmarks/friction_laws.py
	$(BIN)/python benchmarks/step_cost.py
	$(BIN)/python benchmarks/control.py
	$(BIN)/python benchmarks/msl.py
	$(BIN)/python benchmarks/identify_wrist.py
	$(BIN)/python benchmarks/sweep.py $${VSJ_SWEEP_RUNS:-6000} --blocks 3
	$(BIN)/python benchmarks/simulate_cli.py
	$(BIN)/python benchmarks/long_run.py
	$(BIN)/python benchmarks/fmu.py
	$(BIN)/python benchmarks/design.py
	$(BIN)/python benchmarks/explore.py

clean:
	rm -rf $(VENV) reproduction out build src/vsj.egg-info src/vsj/*.so src/vsj/engine/*.so
