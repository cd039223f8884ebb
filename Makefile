# Set-up and main jobs. Only Python 3.11 and make are needed; everything else
# is installed into .venv on first use.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
WARM := $(VENV)/.compiled

.PHONY: install reproduce test bench clean

install: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# numba compiles the engine on first use and caches it beside the sources; this
# step does that up front, with a message, instead of a first run silent for minutes
$(WARM): $(STAMP)
	@echo 'compiling the engine once (numba cache, about 5-7 minutes on 2 cores)...'
	$(BIN)/vsj reproduce --reduced --out $(VENV)/warmup > /dev/null
	touch $(WARM)

reproduce: $(WARM)
	$(BIN)/vsj reproduce --out reproduction

# one worker per core, a test file to a worker: most of the suite's time is numba
# compiling kernels, each worker its own share (both write the shared disk cache).
# No warm-up first: a serial warm-up left one core idle (13-14 minutes in all from
# a fresh clone, against under 10 for the tests compiling on both cores)
test: $(STAMP)
	$(BIN)/python -m pytest -q -n auto --dist loadfile

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py
	$(BIN)/python benchmarks/friction_laws.py
	$(BIN)/python benchmarks/step_cost.py

clean:
	rm -rf $(VENV) reproduction out build src/vsj.egg-info
