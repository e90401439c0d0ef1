# The workbook's whole set-up contract lives here: `make figures`, `make test`, `make lab`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
NB_TIMEOUT ?= 600

# Quiet: Jupyter's new path layout (silences its migration warning). No MPLBACKEND here: kernels use the inline
# backend (figures are stored in the notebooks and shown in `make lab`); headless scripts fall back to Agg.
export JUPYTER_PLATFORM_DIRS := 1
export PYDEVD_DISABLE_FILE_VALIDATION := 1

.PHONY: all setup figures test test-unit test-notebooks lab notebooks execute bench clean

all: test

# (Re)install only when the pins or the package metadata changed.
$(STAMP): environment.txt pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r environment.txt
	touch $(STAMP)

setup: $(STAMP)

## Execute every notebook headless (outputs go to build/, the committed notebooks are untouched)
## and write every report figure to figures/ (PNG + PDF).
figures: $(STAMP)
	$(BIN)/python tools/execute_notebooks.py --output-dir build/notebooks --timeout $(NB_TIMEOUT)
	@ls figures/*.png | wc -l | xargs echo "report figures (PNG) in figures/:"

## Unit tests, then strict nbval over the committed notebook outputs.
test: test-unit test-notebooks

test-unit: $(STAMP)
	$(BIN)/python -m pytest -W error -q tests

test-notebooks: $(STAMP)
	$(BIN)/python -m pytest -W error -q --nbval --nbval-current-env \
	    --nbval-sanitize-with notebooks/nbval_sanitize.cfg \
	    --nbval-cell-timeout 300 -p no:cacheprovider notebooks

## JupyterLab on the notebooks.
lab: $(STAMP)
	$(BIN)/jupyter lab --notebook-dir=notebooks

## Re-execute notebooks in place so their stored outputs (the nbval reference) are current.
## All of them: `make notebooks`; one: `make execute NB=notebooks/01_camera_model.ipynb`.
notebooks: $(STAMP)
	$(BIN)/python tools/execute_notebooks.py --inplace --timeout $(NB_TIMEOUT)

execute: $(STAMP)
	$(BIN)/python tools/execute_notebooks.py --inplace --timeout $(NB_TIMEOUT) $(NB)

## Benchmarks against the peers (prints ratios; see benchmarks/RESULTS.md).
bench: $(STAMP)
	for b in benchmarks/*.py; do $(BIN)/python $$b || exit 1; done

clean:
	rm -rf build figures .pytest_cache
