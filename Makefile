# One-command set-up: every target creates or refreshes the local virtual
# environment (.venv) from this repository's own files (setup.cfg).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: demo test test-fast test-faults lint bench docs setup clean

setup: $(STAMP)

$(STAMP): setup.cfg pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q "torch==2.13.0"
	$(BIN)/python -m pip install -q -e ".[torch,dist,dev]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/spikejdd demo

test: $(STAMP)
	$(BIN)/python -m pytest -q

test-fast: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow"

# the whole fault suite (the default `make test` runs its fast subset)
test-faults: $(STAMP)
	SPIKESIM_FAULTS=full $(BIN)/python -m pytest -q -m faults tests/faults

lint: $(STAMP)
	$(BIN)/ruff check .

# the user guides and the API reference (autodoc + numpydoc); warnings are errors
docs: $(STAMP)
	$(BIN)/python -m sphinx -W --keep-going -q -b html docs docs/_build/html
	@echo "open docs/_build/html/index.html"

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_kernel.py

clean:
	rm -rf $(VENV) demo_out .pytest_cache docs/_build
