# Two commands set everything up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-fast lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/wncs run scenarios/jcstr_wncs.yaml --out runs/jcstr_wncs

test: $(STAMP)
	$(BIN)/python -m pytest

test-fast: $(STAMP)
	$(BIN)/python -m pytest -m 'not slow'

lint: $(STAMP)
	$(BIN)/ruff check .

bench: $(STAMP)
	$(BIN)/python bench/engines.py
	$(BIN)/python bench/section3c.py
	$(BIN)/python bench/realtime.py
	$(BIN)/python bench/wncsca_figures.py
	$(BIN)/python bench/wncsca_methods.py --quick
	$(BIN)/python bench/wncsca_latency.py

clean:
	rm -rf $(VENV) runs
