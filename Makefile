# The README's two commands: `make demo` and `make test`. Both create .venv when missing.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-dev
CORE_STAMP := $(VENV)/.installed

.PHONY: demo test lint bench clean

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)

# The demo needs only the core dependencies (a cold install of the dev extras
# roughly doubles the download); the tests need the dev extra.
$(CORE_STAMP): pyproject.toml | $(VENV)/bin/python
	$(PY) -m pip install --quiet -e .
	touch $(CORE_STAMP)

$(STAMP): pyproject.toml | $(VENV)/bin/python
	$(PY) -m pip install --quiet -e ".[dev]"
	$(PY) -m pip install --quiet --no-deps "pyNastran>=1.4,<1.5"
	touch $(STAMP) $(CORE_STAMP)

demo: $(CORE_STAMP)
	$(PY) -m robustctl demo --out out

test: $(STAMP)
	$(PY) -m pytest -n 2 --dist loadfile -q --durations=15 tests --nbmake notebooks

lint: $(STAMP)
	$(VENV)/bin/ruff check robustctl tests benchmarks

bench: $(STAMP)
	$(PY) -m benchmarks

clean:
	rm -rf $(VENV) out .pytest_cache
