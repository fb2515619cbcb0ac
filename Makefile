# Two commands set everything up on a fresh machine: `make demo` and `make test`.
# Both install from requirements.lock (every dependency, transitive and build ones included,
# pinned with hashes); `make lock` refreshes it after a change to pyproject.toml's dependencies.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
PIP_TOOLS := pip-tools==7.6.2
LOCK_VENV := .venv-lock
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: demo test test-fast lint docs lock bench clean browser

$(STAMP): requirements.lock pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --require-hashes --no-deps -r requirements.lock
	$(BIN)/python -m pip install --quiet --no-deps --no-build-isolation -e .
	$(BIN)/python -m pip check
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/wncs run scenarios/jcstr_wncs.yaml --out runs/jcstr_wncs --force

test: $(STAMP) browser
	$(BIN)/python -m pytest

# The dashboard's end-to-end test drives Debian's chromium with Playwright (which cannot download
# its own browsers here): install the package when it is missing.
browser:
	@command -v chromium >/dev/null 2>&1 || { \
		echo "installing Debian's chromium for the dashboard's browser test"; \
		$(SUDO) apt-get update -qq && \
		DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq chromium >/dev/null; }

test-fast: $(STAMP)
	$(BIN)/python -m pytest -m 'not slow'

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check --exclude '*.md' .
	$(BIN)/mypy --strict bus_schemas core kernel scenario agents/wncsca

# The documentation site into site/ (docs/hooks.py generates the reference pages from the code);
# --strict: a broken link or anchor, or a page left out of the nav, fails the build.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet --site-dir site

# Re-resolve every dependency to the newest versions pyproject.toml allows and pin them with
# hashes. Run it after editing dependencies, or on purpose to take upgrades (then `make test`).
lock:
	$(PYTHON) -m venv $(LOCK_VENV)
	$(LOCK_VENV)/bin/python -m pip install --quiet $(PIP_TOOLS)
	$(LOCK_VENV)/bin/pip-compile --quiet --generate-hashes --allow-unsafe --all-build-deps \
		--no-emit-index-url --no-emit-find-links --extra dev --strip-extras \
		-o requirements.lock pyproject.toml

bench: $(STAMP)
	$(BIN)/python bench/engines.py
	$(BIN)/python bench/section3c.py
	$(BIN)/python bench/realtime.py
	$(BIN)/python bench/wncsca_figures.py
	$(BIN)/python bench/wncsca_methods.py --quick
	$(BIN)/python bench/wncsca_scale.py --repeat 1
	$(BIN)/python bench/wncsca_latency.py
	$(BIN)/python bench/tsch_slotframes.py
	$(BIN)/python bench/startup.py
	$(BIN)/python bench/dashboard_load.py

clean:
	rm -rf $(VENV) $(LOCK_VENV) runs site
