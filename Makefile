# hammerstein_ctrl: the two commands of the README, plus helpers.
#   make demo   create .venv, install, reproduce the paper's TRS comparison, write figures
#   make test   create .venv, install with test extras, run the whole test suite
#   make notebooks  execute notebooks/*.ipynb in place, saving their outputs (figures)
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test bench notebooks install clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/hammerstein-ctrl reproduce trs --out results/trs

test: $(STAMP)
	$(BIN)/python -m pytest -q

notebooks: $(STAMP)
	$(BIN)/python notebooks/run_notebooks.py

bench: $(STAMP)
	$(BIN)/hammerstein-ctrl bench --methods nspsa nlspsa spsa amvo-sca

clean:
	rm -rf $(VENV) results .pytest_cache
