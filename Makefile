# Two entry points, both safe on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
STAMP := .venv-stamp

.PHONY: setup demo test lint

$(STAMP): pyproject.toml .ci/setup
	bash .ci/setup
	@touch $(STAMP)

setup: $(STAMP)

demo: $(STAMP)
	pavonine demo out/demo

lint: $(STAMP)
	ruff check .
	ruff format --check .

test: lint
	$(PYTHON) -m pytest
