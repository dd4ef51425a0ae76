# hammerstein_ctrl: the two commands of the README, plus helpers.
#   make demo   create .venv, install, reproduce the paper's TRS comparison, write figures
#   make test   create .venv, install with test extras, run the test suite (all but the tests marked slow)
#               on every core (pytest-xdist; one test file per worker, so a file's compiled kernels are built once)
#   make test-slow  the tests marked slow (notebooks, studies, CLI examples); .ci/run runs both
#   make bench      the speed benchmark, then the tests marked timing (wall-clock bounds: never in make test)
#   make warmup     compile the kernels of the common structures now, on every core (once per machine)
#   make lint       ruff under the project's configuration (pyproject.toml); .ci/run runs it first
#   make notebooks  execute notebooks/*.ipynb in place, saving their outputs (figures)
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test test-slow lint bench notebooks install clean warmup

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/hammerstein-ctrl reproduce trs --out results/trs

test: $(STAMP)
	$(BIN)/python -m pytest -q -n auto --dist loadfile

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -n auto --dist loadfile -m 'slow and not timing'

warmup: $(STAMP)
	$(BIN)/hammerstein-ctrl warmup

lint: $(STAMP)
	$(BIN)/ruff check hammerstein_ctrl tests benchmarks notebooks

notebooks: $(STAMP)
	$(BIN)/python notebooks/run_notebooks.py

bench: $(STAMP)
	$(BIN)/hammerstein-ctrl bench --methods nspsa nlspsa spsa amvo-sca
	$(BIN)/python -m pytest -q -m timing

clean:
	rm -rf $(VENV) results .pytest_cache
