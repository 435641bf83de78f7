# Every target creates .venv and installs the project with what it needs: nothing by hand.
# Test tiers (docs/architecture.md, "Tests"):
#   make test              lint, then every in-process test in parallel (pytest-xdist): minutes
#   make test-integration  processes, sockets, browsers, real time: one at a time
#   make test-slow         the long proofs (deep campaigns, full-suite agreement, stress)
#   make test-all          all three: what CI runs
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
# each tier's per-test durations (JUnit XML) land here; CI keeps them beside its log
REPORTS ?= test-reports
PYTEST := $(BIN)/pytest -q
# byte code cached: pytest's rewritten test modules, the xdist workers and every rig or emulator process a test
# starts compile the project once, not each time (some shells set PYTHONDONTWRITEBYTECODE)
unexport PYTHONDONTWRITEBYTECODE

.PHONY: demo test test-integration test-slow test-all test-tools coverage bench lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	-git config core.hooksPath .githooks 2>/dev/null  # commit subjects ≤ 72 characters (.githooks/commit-msg)
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/rig demo

# ruff on everything; mypy on the packages ([tool.mypy] in pyproject.toml), every `type: ignore` there with its reason
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/mypy
	$(PYTEST) tests/test_type_ignores.py

# the README's test command: lint and the fast tier (every test not marked integration or slow), in parallel;
# a test over its time budget fails with its stack (pytest-timeout), one near it is listed (tests/conftest.py)
test: $(STAMP) lint
	$(PYTEST) -n auto -m "not integration and not slow" --timeout=300 --junitxml=$(REPORTS)/fast.xml

# the tests that start processes, open sockets or drive a browser: one at a time
test-integration: $(STAMP) test-tools
	$(PYTEST) -m "integration and not slow" --timeout=900 --durations=15 --junitxml=$(REPORTS)/integration.xml

# the long proofs: the in-process ones in parallel, then those with processes one at a time
test-slow: $(STAMP) test-tools
	$(PYTEST) -n auto -m "slow and not integration" --timeout=1800 --durations=10 --junitxml=$(REPORTS)/slow.xml
	$(PYTEST) -m "slow and integration" --timeout=1800 --durations=10 --junitxml=$(REPORTS)/slow-integration.xml

test-all: test test-integration test-slow

# line coverage of the packages ([tool.coverage] in pyproject.toml: the rig, emulator and console processes the
# tests start are measured too) over the three tiers, the fast tier's own figure first; every tier runs even when
# one fails, and the exit status says whether all passed
coverage: $(STAMP) test-tools
	@mkdir -p $(REPORTS); $(BIN)/coverage erase; status=0; \
	$(PYTEST) -n auto -m "not integration and not slow" --timeout=300 --cov --cov-report= || status=1; \
	echo "fast tier: $$($(BIN)/coverage report --format=total) % of the packages' lines" | tee $(REPORTS)/coverage.txt; \
	$(PYTEST) -m "integration and not slow" --timeout=900 --cov --cov-append --cov-report= || status=1; \
	$(PYTEST) -n auto -m "slow and not integration" --timeout=1800 --cov --cov-append --cov-report= || status=1; \
	$(PYTEST) -m "slow and integration" --timeout=1800 --cov --cov-append --cov-report= || status=1; \
	echo "all tiers: $$($(BIN)/coverage report --format=total) % of the packages' lines" | tee -a $(REPORTS)/coverage.txt; \
	$(BIN)/coverage report --skip-covered --sort=cover >> $(REPORTS)/coverage.txt; exit $$status

# Debian's programs that tests use as the other end: Chromium (the console's browser tests) and hdf5-tools (h5dump
# reads a session file); installed where this user may (root with apt-get), else said: those tests are then skipped
DEBIAN_TOOLS := chromium:chromium h5dump:hdf5-tools
test-tools:
	@missing=""; for pair in $(DEBIAN_TOOLS); do command -v "$${pair%%:*}" >/dev/null 2>&1 || missing="$$missing $${pair#*:}"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing Debian's$$missing for the tests that use them"; \
	    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing >/dev/null; } \
	      || echo "warning: could not install$$missing: the tests that use them will be SKIPPED" >&2; \
	  else \
	    echo "warning:$$missing not installed (apt-get install$$missing, as root): the tests that use them will be SKIPPED" >&2; \
	  fi; \
	fi

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
	rm -rf $(VENV) build *.egg-info $(REPORTS) .coverage .coverage.*
