# rowtrack: `make run` (the main job) and `make test` (the test suite).
# Both create .venv and install the package with its test extras when needed.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.rowtrack-installed
# Parallel test workers; CI machines have 2 cores.
JOBS   ?= 2

.PHONY: run test test-icarus bench clean venv

venv: $(STAMP)

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $@

# Options for `rowtrack run`, e.g. RUN_ARGS="--rows 32 --frames 3 --sim icarus".
RUN_ARGS ?=

run: $(STAMP)
	$(VENV)/bin/rowtrack run $(RUN_ARGS)

test: $(STAMP)
	$(PY) -m pytest -n $(JOBS) $(PYTEST_ARGS)

bench: $(STAMP)
	$(VENV)/bin/rowtrack bench --jobs $(JOBS) --write-docs docs/results
	$(VENV)/bin/rowtrack synth-report --write-docs docs/results

clean:
	rm -rf build
