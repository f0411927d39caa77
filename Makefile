# Two commands do all the set-up on a fresh machine:
#   make        build .venv on first use, then run the main job on defaults
#   make test   build .venv on first use, then run the test suite (serially and on 2 MPI ranks)
#   make lint   ruff over the repository (the rules in pyproject.toml)
#   make docs   the documentation site (Sphinx, demos executed) -> docs/_build/html
VENV ?= .venv
OUT ?= results
NP ?= 2
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: run install test test-slow lint docs clean
run: $(STAMP)
	$(VENV)/bin/fingertip run line-load --out $(OUT)/line-load

install: $(STAMP)

test: $(STAMP)
	$(PY) scripts/run_tests.py --np $(NP)

test-slow: $(STAMP)
	$(PY) -m pytest -m slow

lint: $(STAMP)
	$(VENV)/bin/ruff check .

DOCS_STAMP := $(VENV)/.docs-installed
docs: $(DOCS_STAMP)
	$(VENV)/bin/sphinx-build -W --keep-going -b html docs docs/_build/html

$(DOCS_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e ".[docs]"
	touch $@

$(STAMP): pyproject.toml scripts/install.sh
	VENV=$(VENV) bash scripts/install.sh
	touch $@

clean:
	rm -rf $(VENV) $(OUT) docs/_build
