# Two entry points for a newcomer: `make repro` (set up + run the pipeline) and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
export DVC_NO_ANALYTICS := 1
export PYTHONUNBUFFERED := 1

.PHONY: setup repro test bench clean

$(BIN)/emogait: pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

setup: $(BIN)/emogait
	test -d .dvc || $(BIN)/dvc init --quiet
	$(BIN)/dvc config --local core.analytics false

repro: setup
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/dvc repro

test: setup
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python -m pytest $(PYTEST_ARGS)

bench: setup
	$(BIN)/python benchmarks/ingest.py
	$(BIN)/python benchmarks/contacts.py
	$(BIN)/python benchmarks/generate.py

clean:
	rm -rf $(VENV) data reports .pytest_cache
