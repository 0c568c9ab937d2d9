# Two entry points for a fresh machine (Debian, Python >= 3.11): `make run` and `make test`.
# Both install the Debian rendering libraries if missing, create .venv and install the package.
PY ?= python3
# Test processes (pytest-xdist): the CI machine's 2 cores.
TEST_WORKERS ?= 2
VENV := .venv
STAMP := $(VENV)/.installed

.PHONY: run test lint typecheck setup

$(STAMP): pyproject.toml .ci/system-deps.sh
	bash .ci/system-deps.sh
	$(PY) -m venv $(VENV)
	$(VENV)/bin/pip install -q --upgrade pip
	$(VENV)/bin/pip install -q -e '.[dev,export,cluster,rl,monitor]'
	touch $(STAMP)

setup: $(STAMP)

run: $(STAMP)
	$(VENV)/bin/cyber-rodent evolve

test: $(STAMP)
	$(VENV)/bin/python -m pytest -n $(TEST_WORKERS)

lint: $(STAMP)
	$(VENV)/bin/ruff check cyber_rodent behaviours evolution tests benchmarks

typecheck: $(STAMP)
	$(VENV)/bin/mypy
