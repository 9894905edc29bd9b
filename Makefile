# Two entry points for a newcomer: `make repro` (set up + run the pipeline) and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
export DVC_NO_ANALYTICS := 1
export PYTHONUNBUFFERED := 1

.PHONY: setup repro test test-fast golden bench clean

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

# The tests not marked slow (no full ingest of the default data, no DVC): under a minute on 2 cores. It needs the
# installed environment only (no `dvc config`), so it starts at once.
test-fast: $(BIN)/emogait
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python -m pytest -m "not slow" $(PYTEST_ARGS)

# Rewrite tests/golden/*.json from the current code (after a deliberate change; say why in the commit).
golden: $(BIN)/emogait
	EMOGAIT_UPDATE_GOLDEN=1 PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python -m pytest tests/test_golden.py -m "not slow" $(PYTEST_ARGS)

bench: setup
	$(BIN)/python benchmarks/ingest.py
	$(BIN)/python benchmarks/contacts.py
	$(BIN)/python benchmarks/generate.py

clean:
	rm -rf $(VENV) data reports .pytest_cache
