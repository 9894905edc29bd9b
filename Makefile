# Two entry points for a newcomer: `make repro` (set up + run the pipeline) and `make test`.
PYTHON ?= python3
VENV := .venv
PIP_VERSION := 26.3
BIN := $(VENV)/bin
export DVC_NO_ANALYTICS := 1
export PYTHONUNBUFFERED := 1

.PHONY: setup repro test test-fast golden bench lock clean

# Installed from the lock file (every package pinned with its sha256; `make lock` rewrites it), then the project itself
# without dependencies: two machines, or two days, get the same libraries, so the same bytes.
$(BIN)/emogait: pyproject.toml requirements.lock
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet pip==$(PIP_VERSION)
	$(BIN)/python -m pip install --quiet --require-hashes -r requirements.lock
	$(BIN)/python -m pip install --quiet --no-deps --no-build-isolation -e .
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
	$(BIN)/python benchmarks/fuzz.py

# Rewrite requirements.lock from pyproject.toml (the ranges library users get) after a dependency change. pip-tools
# runs in its own environment so that the project's stays exactly what the lock says.
lock:
	test -x .venv-lock/bin/pip-compile || ($(PYTHON) -m venv .venv-lock && .venv-lock/bin/pip install --quiet pip-tools==7.6.2)
	.venv-lock/bin/pip-compile --quiet --generate-hashes --allow-unsafe --strip-extras --extra test \
	  --no-emit-index-url --no-emit-find-links -o requirements.lock pyproject.toml

clean:
	rm -rf $(VENV) data reports .pytest_cache
