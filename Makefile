# roslan — quick start: `make demo`, `make test`.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
DEV    := $(VENV)/.installed-dev

.PHONY: demo test lint typecheck bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip

# roslan and its runtime dependencies (all the demo needs)
$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install -e .
	touch $(STAMP)

# plus the development extras (tests, linters, the readers tests compare against)
$(DEV): $(STAMP)
	$(BIN)/python -m pip install -e '.[dev]'
	touch $(DEV)

demo: $(STAMP)
	$(BIN)/roslan simulate -o out --overwrite

test: $(DEV)
	$(BIN)/python -m pytest -n 2 tests

lint: $(DEV)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/ruff format --check src tests benchmarks
	$(BIN)/mypy

bench: $(DEV)
	for b in benchmarks/bench_*.py; do $(BIN)/python $$b || exit 1; done

clean:
	rm -rf $(VENV) out out_* build src/*.egg-info .pytest_cache .mypy_cache .ruff_cache
