# Set-up and main jobs. Only Python 3.11 and make are needed; everything else
# is installed into .venv on first use.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install reproduce test bench clean

install: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	@echo 'compiling the engine once (numba cache, about 2-3 minutes)...'
	$(BIN)/vsj reproduce --reduced --out $(VENV)/warmup > /dev/null
	$(BIN)/vsj linearize > /dev/null
	touch $(STAMP)

reproduce: $(STAMP)
	$(BIN)/vsj reproduce --out reproduction

# one worker per core, a test file to a worker: most of the suite's time is numba
# compiling kernels (each worker its own share, both writing the shared disk cache)
test: $(STAMP)
	$(BIN)/python -m pytest -q -n auto --dist loadfile

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py
	$(BIN)/python benchmarks/friction_laws.py
	$(BIN)/python benchmarks/step_cost.py

clean:
	rm -rf $(VENV) reproduction out build src/vsj.egg-info
