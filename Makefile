# The README's two commands: `make demo` and `make test`. Both create .venv when missing.
# Both install from constraints/test.txt: the exact releases the suite is known to pass on
# (`make pins` refreshes them; `make test-latest` runs the suite on the newest releases).
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-dev
CORE_STAMP := $(VENV)/.installed
CONSTRAINTS := constraints/test.txt
LATEST := .venv-latest
PINS_VENV := .venv-pins
# Whole files go to the workers in tests/conftest.py's order (files with the most slow cases and
# the notebooks first): xdist's default reorder by test count would start the two demo files and
# the notebooks (1-2 long tests each) last, behind the property suites' thousands of quick cases.
# `make test` runs every case not marked slow (target: under 10 minutes on 2 cores); `make
# test-slow` runs the slow ones; CI (.ci/run) runs both.
PYTEST_RUN := -n 2 --dist loadfile --no-loadscope-reorder -q --durations=15
# A notebook cell may run a whole design (06's LQG beside mu: 250 CPU-s): nbmake's default cell
# timeout (300 s wall) failed it on a loaded machine, so cells get 30 minutes.
NBMAKE := --nbmake notebooks --nbmake-timeout=1800
PYTEST_ARGS := $(PYTEST_RUN) -m "not slow" tests $(NBMAKE)
PYTEST_SLOW := $(PYTEST_RUN) -m slow tests
PYTEST_ALL := $(PYTEST_RUN) tests $(NBMAKE)
# pyNastran pins numpy<2: installed without its dependencies (see pyproject's nastran extra)
NASTRAN := "pyNastran>=1.4,<1.5"

.PHONY: demo test test-slow test-all test-loaded test-latest pins lint bench clean

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)

# The demo needs only the core dependencies (a cold install of the dev extras
# roughly doubles the download); the tests need the dev extra.
$(CORE_STAMP): pyproject.toml $(CONSTRAINTS) | $(VENV)/bin/python
	$(PY) -m pip install --quiet -c $(CONSTRAINTS) -e .
	touch $(CORE_STAMP)

$(STAMP): pyproject.toml $(CONSTRAINTS) | $(VENV)/bin/python
	$(PY) -m pip install --quiet -c $(CONSTRAINTS) -e ".[dev]"
	$(PY) -m pip install --quiet --no-deps -c $(CONSTRAINTS) $(NASTRAN)
	touch $(STAMP) $(CORE_STAMP)

demo: $(CORE_STAMP)
	$(PY) -m robustctl demo --out out

test: $(STAMP)
	$(PY) -m pytest $(PYTEST_ARGS)

test-slow: $(STAMP)
	$(PY) -m pytest $(PYTEST_SLOW)

test-all: $(STAMP)
	$(PY) -m pytest $(PYTEST_ALL)

# The suite on a busy machine: two busy loops (one per core here) run beside it and end with
# this recipe's shell (they poll their parent), so no outcome may depend on time or load.
BUSY := import os; p = os.getppid()\nwhile os.getppid() == p: pass
test-loaded: $(STAMP)
	$(PY) -c "$$(printf '$(BUSY)')" & a=$$!; $(PY) -c "$$(printf '$(BUSY)')" & b=$$!; \
	$(PY) -m pytest $(PYTEST_ALL); rc=$$?; kill $$a $$b 2>/dev/null; exit $$rc

# The newest releases the pyproject ranges allow, in a venv of their own; allowed to differ.
test-latest:
	test -x $(LATEST)/bin/python || $(PYTHON) -m venv $(LATEST)
	$(LATEST)/bin/python -m pip install --quiet --upgrade --upgrade-strategy eager -e ".[dev]"
	$(LATEST)/bin/python -m pip install --quiet --upgrade --no-deps $(NASTRAN)
	$(LATEST)/bin/python -m pip freeze --exclude-editable
	$(LATEST)/bin/python -m pytest $(PYTEST_ALL)

# Re-resolve the dev install from scratch (no constraints) and write its exact releases to
# $(CONSTRAINTS), marked for this interpreter's Python and newer (older ones resolve freely).
pins:
	rm -rf $(PINS_VENV)
	$(PYTHON) -m venv $(PINS_VENV)
	$(PINS_VENV)/bin/python -m pip install --quiet -e ".[dev]"
	$(PINS_VENV)/bin/python -m pip install --quiet --no-deps $(NASTRAN)
	$(PINS_VENV)/bin/python -c 'import platform, sys, datetime; \
	print("# Exact releases `make test` installs (pip install -c). Refresh: make pins"); \
	print("# Resolved", datetime.date.today(), "on Python", platform.python_version(), sys.platform)' > $(CONSTRAINTS).new
	$(PINS_VENV)/bin/python -m pip freeze --exclude-editable | grep -v -i '^robustctl\|^#\|^-e' \
	  | sed "s/\$$/ ; python_version >= \"$$($(PINS_VENV)/bin/python -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')\"/" \
	  >> $(CONSTRAINTS).new
	mv $(CONSTRAINTS).new $(CONSTRAINTS)
	rm -rf $(PINS_VENV)

lint: $(STAMP)
	$(VENV)/bin/ruff check robustctl tests benchmarks

bench: $(STAMP)
	$(PY) -m benchmarks

clean:
	rm -rf $(VENV) $(LATEST) $(PINS_VENV) out .pytest_cache
