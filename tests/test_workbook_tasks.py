"""tools/workbook.py's parallel test runs: the worker count, its bad input, and one BLAS thread per worker."""
import json
import pathlib
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
import workbook  # noqa: E402


@pytest.mark.parametrize("value, expected", [("1", []), ("3", ["-n", "3"]), (" 2 ", ["-n", "2"])])
def test_workbook_jobs_sets_the_worker_count(monkeypatch, value, expected):
    monkeypatch.setenv("WORKBOOK_JOBS", value)
    assert workbook.parallel_args() == expected


def test_default_worker_count_is_one_per_core_at_most_four(monkeypatch):
    monkeypatch.delenv("WORKBOOK_JOBS", raising=False)
    monkeypatch.setattr(workbook.os, "cpu_count", lambda: 16)
    assert workbook.parallel_args() == ["-n", "4"]
    monkeypatch.setattr(workbook.os, "cpu_count", lambda: 1)
    assert workbook.parallel_args() == []


@pytest.mark.parametrize("value", ["two", "-1", "1.5"])
def test_bad_workbook_jobs_is_a_named_error(monkeypatch, value):
    monkeypatch.setenv("WORKBOOK_JOBS", value)
    with pytest.raises(workbook.TaskError, match="WORKBOOK_JOBS must be a whole number"):
        workbook.parallel_args()


def test_workers_get_one_blas_thread_unless_the_caller_chose(monkeypatch):
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "8")
    env = workbook.worker_env(["-n", "2"], {"NPY_DISABLE_CPU_FEATURES": "X86_V4"})
    assert env == {"NPY_DISABLE_CPU_FEATURES": "X86_V4", "OMP_NUM_THREADS": "1"}
    assert workbook.worker_env([], None) == {}


def test_stored_run_seconds_sums_the_cell_timings(tmp_path):
    cell = {"metadata": {"execution": {"iopub.execute_input": "2026-11-23T10:00:00.000Z",
                                       "shell.execute_reply": "2026-11-23T10:00:02.500Z"}}}
    nb = tmp_path / "a.ipynb"
    nb.write_text(json.dumps({"cells": [cell, cell, {"metadata": {}}]}), encoding="utf-8")
    assert workbook.stored_run_seconds(nb) == pytest.approx(5.0)
    (tmp_path / "bad.ipynb").write_text("not json", encoding="utf-8")
    assert workbook.stored_run_seconds(tmp_path / "bad.ipynb") == 0.0
