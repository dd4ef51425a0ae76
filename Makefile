# hammerstein_ctrl: the two commands of the README, plus helpers.
#   make demo       create .venv, install (building the compiled core once), reproduce the paper's TRS comparison,
#                   write figures
#   make test       create .venv, install with test extras, run the test suite (all but the tests marked slow) on
#                   every core against the installed package (pytest-xdist; one test file per worker)
#   make test-slow  the tests marked slow (notebooks, studies, CLI examples); .ci/run runs both
#   make wheel      the platform wheel of this machine into dist/ (what pip install takes: no compiler needed)
#   make bench      the speed benchmark, then the tests marked timing (wall-clock bounds: never in make test)
#   make lint       ruff under the project's configuration (pyproject.toml); .ci/run runs it first
#   make notebooks  execute notebooks/*.ipynb in place, saving their outputs (figures)
#   make docs       the documentation site into docs/_build/html (Sphinx, warnings and broken references are
#                   errors; the notebooks shown with their committed outputs)
#
# The package has one compiled extension (hammerstein_ctrl._core, sources in hammerstein_ctrl/_csrc), built when it
# is installed, so the tests always run against the installed package: an edited source is built again (only what
# changed, in build/venv) by the next make.  Building from source needs a C and C++ compiler (gcc and g++, clang, or
# MSVC); a wheel needs none.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
TOOLS  := $(VENV)/.build-tools
STAMP  := $(VENV)/.installed
# what the installed package is built from
SOURCES := pyproject.toml meson.build data/trs_reconstruction.csv \
           $(shell find hammerstein_ctrl -type f ! -path '*/__pycache__/*' ! -name '*.pyc')
PYTEST := $(BIN)/pytest -q -n auto --dist loadfile tests --pyargs hammerstein_ctrl

.PHONY: demo test test-slow lint bench notebooks docs install wheel clean

$(TOOLS):
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet "meson-python>=0.15" "meson>=1.1" ninja
	touch $@

# a non-editable install: the compiled core is built here (incrementally, in build/venv), never when it runs
$(STAMP): $(TOOLS) $(SOURCES)
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python -m pip install --quiet --no-build-isolation \
	    -Cbuild-dir=build/venv '.[test]'
	touch $@

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/hammerstein-ctrl reproduce trs --out results/trs

test: $(STAMP)
	$(PYTEST)

test-slow: $(STAMP)
	$(PYTEST) -m 'slow and not timing'

wheel: $(TOOLS)
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python -m pip wheel --quiet --no-deps --no-build-isolation \
	    -Cbuild-dir=build/wheel -w dist .

lint: $(STAMP)
	$(BIN)/ruff check hammerstein_ctrl tests benchmarks notebooks

notebooks: $(STAMP)
	$(BIN)/python notebooks/run_notebooks.py

DOCS_STAMP := $(VENV)/.docs-installed
$(DOCS_STAMP): $(STAMP) pyproject.toml
	$(BIN)/python -m pip install --quiet "sphinx>=7.2" "pydata-sphinx-theme>=0.15" "numpydoc>=1.6" "myst-nb>=1.0"
	touch $@

docs: $(DOCS_STAMP)
	rm -rf docs/_build docs/api/generated
	cd docs && $(abspath $(BIN))/python -m sphinx -b html -W --keep-going -q . _build/html
	@echo "docs: $$(find docs/_build/html -name '*.html' | wc -l) pages in docs/_build/html"

bench: $(STAMP)
	$(BIN)/python benchmarks/speed.py --methods nspsa nlspsa spsa amvo-sca
	$(BIN)/pytest -q tests --pyargs hammerstein_ctrl -m timing

clean:
	rm -rf $(VENV) build dist results .pytest_cache docs/_build docs/api/generated
