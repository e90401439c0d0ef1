# The workbook's set-up contract: `make figures`, `make test`, `make lab`.
# Every target delegates to tools/workbook.py, the one cross-platform task script (Windows runs it directly:
# `py -3.11 tools\workbook.py test`). It checks the interpreter first (CPython 3.11.5 to 3.13), creates or
# refreshes .venv from environment.txt, and never reuses a .venv whose install did not finish.
PYTHON ?= python3
TASK   := $(PYTHON) tools/workbook.py

.PHONY: all setup figures test test-unit test-notebooks lab notebooks execute bench student grade submission student-check clean distclean

all: test

## Create or refresh .venv (exact pins of environment.txt, plus the optional peers where wheels exist).
setup:
	@$(TASK) setup

## Execute every notebook headless (copies go to build/notebooks; the committed notebooks are untouched)
## and write every report figure to figures/ (PNG + PDF).
figures:
	@$(TASK) figures

## Unit tests, then strict nbval over the committed notebook outputs (with CI=true: two more lowered-CPU passes).
test:
	@$(TASK) test

test-unit:
	@$(TASK) test-unit

test-notebooks:
	@$(TASK) test-notebooks

## JupyterLab on the notebooks.
lab:
	@$(TASK) lab

## Re-execute notebooks in place so their stored outputs (the nbval reference) are current.
## All of them: `make notebooks`; one: `make execute NB=notebooks/01_camera_model.ipynb`.
notebooks:
	@$(TASK) notebooks

execute:
	@$(TASK) execute $(NB)

## Benchmarks against the peers (prints ratios; see benchmarks/RESULTS.md).
bench:
	@$(TASK) bench

## The student edition (exercise bodies replaced by stubs; tools/exercises.toml) in build/student.
student:
	@$(TASK) student

## Check the exercises (each runs only its own tests, tests/exercises/): `make grade EX=name` one, `make grade` all.
grade:
	@$(TASK) grade $(EX)

## The student's work in one zip to hand in (exercise files and notebooks): submission.zip.
submission:
	@$(TASK) submission

## The CI check of the student edition (every exercise alone, every notebook with only its exercises); CI=true make test runs it.
student-check:
	@$(TASK) student-check

## build/, figures/ and caches; distclean also removes .venv.
clean:
	@$(TASK) clean

distclean:
	@$(TASK) distclean
