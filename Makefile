# The README's two commands, both safe on a fresh machine: `make demo` and `make test`.
# Both first run .ci/setup once (again when pyproject.toml, constraints.txt or .ci/setup change):
# Debian packages where it can (root and apt-get), else it says what to install; then the project's
# own virtual environment .venv with Pavonine and every extra, at the versions of constraints.txt.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.pavonine-setup

.PHONY: setup demo test lint lock

$(STAMP): pyproject.toml constraints.txt .ci/setup
	PYTHON="$(PYTHON)" VENV="$(VENV)" bash .ci/setup
	@touch $(STAMP)

setup: $(STAMP)

demo: $(STAMP)
	$(BIN)/pavonine demo -o out/demo

# ruff (lint and format), then the house's import contract (pyproject.toml, docs/house.md).
lint: $(STAMP)
	$(BIN)/python -m ruff check .
	$(BIN)/python -m ruff format --check .
	$(BIN)/lint-imports --no-cache

# The environment's bin first: wheels bring command-line tools the tests run (mxvalidate, oiiotool).
# One pytest worker per core (pytest-xdist), each test file on one worker so its module fixtures
# are built once.
test: lint
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python -m pytest --numprocesses=auto --dist=loadfile

# Re-pin constraints.txt to the versions installed in .venv (after changing a dependency).
lock: $(STAMP)
	$(BIN)/python .ci/lock.py > constraints.txt
