# kincal: `make demo` and `make test` set up .venv themselves on a fresh clone.
PYTHON ?= python3
VENV   ?= .venv
PY      = $(VENV)/bin/python
STAMP   = $(VENV)/.installed

.PHONY: setup demo test bench clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[dev]'
	touch $(STAMP)

demo: setup
	$(VENV)/bin/kincal demo

test: setup
	$(PY) -m pytest -q

bench: setup
	$(PY) benchmarks/core.py

clean:
	rm -rf $(VENV) build src/*.egg-info .pytest_cache
