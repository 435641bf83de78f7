# Every target creates .venv and installs the project with what it needs: nothing by hand.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: demo test test-slow bench lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/rig demo

# ruff on everything; mypy on the packages ([tool.mypy] in pyproject.toml: the modules not yet clean listed there)
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/mypy

# the README's test command: lint and every test not marked slow (minutes)
test: $(STAMP) lint
	$(BIN)/pytest -q -m "not slow" --durations=25

# the long tests: full-suite agreement with the reference, stress, published pulse thresholds
test-slow: $(STAMP)
	$(BIN)/pytest -q -m slow --durations=15

bench: $(STAMP)
	$(BIN)/python benchmarks/engine.py
	$(BIN)/python benchmarks/prepare.py
	$(BIN)/python benchmarks/stream.py --transport mavlink
	$(BIN)/python benchmarks/stream.py --transport zenoh
	$(BIN)/python benchmarks/stream.py --transport canopen
	$(BIN)/python benchmarks/session_logging.py
	$(BIN)/python benchmarks/study.py
	$(BIN)/python benchmarks/report.py

clean:
	rm -rf $(VENV) build *.egg-info
