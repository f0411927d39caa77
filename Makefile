# Two commands do all the set-up on a fresh machine:
#   make        build .venv on first use, then run the main job on defaults
#   make test   build .venv on first use, then run the test suite (serially and on 2 MPI ranks)
VENV ?= .venv
OUT ?= results
NP ?= 2
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: run install test test-slow clean
run: $(STAMP)
	$(VENV)/bin/fingertip run line-load --out $(OUT)/line-load

install: $(STAMP)

test: $(STAMP)
	$(PY) scripts/run_tests.py --np $(NP)

test-slow: $(STAMP)
	$(PY) -m pytest -m slow

$(STAMP): pyproject.toml scripts/install.sh
	VENV=$(VENV) bash scripts/install.sh
	touch $@

clean:
	rm -rf $(VENV) $(OUT)
