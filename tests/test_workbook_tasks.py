"""tools/workbook.py's parallel test runs: the worker count, its bad input, one BLAS thread per worker, and which
notebooks run again when their kernel did not start."""
import json
import pathlib
import sys
from xml.sax.saxutils import quoteattr

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


def _report(tmp_path, cases):
    """A junit-xml report as pytest writes it for nbval items: (notebook, cell, None | ("error", message))."""
    rows = []
    for notebook, cell, bad in cases:
        body = "" if bad is None else "<%s message=%s>trace</%s>" % (bad[0], quoteattr(bad[1]), bad[0])
        rows.append('<testcase classname="notebooks.%s" name="Cell %d" time="0.1">%s</testcase>'
                    % (notebook, cell, body))
    path = tmp_path / "report.xml"
    path.write_text('<?xml version="1.0" encoding="utf-8"?><testsuites><testsuite name="pytest">%s</testsuite>'
                    "</testsuites>" % "".join(rows))
    return path


def test_only_notebooks_whose_kernel_did_not_start_run_again(tmp_path):
    notebooks = [workbook.ROOT / "notebooks" / n for n in ("01_a.ipynb", "02_b.ipynb", "03_c.ipynb")]
    died = ("error", 'failed on setup with "RuntimeError: Kernel died before replying to kernel_info"')
    report = _report(tmp_path, [("01_a.ipynb", 0, None), ("02_b.ipynb", 0, died), ("02_b.ipynb", 1, died),
                                ("03_c.ipynb", 0, None)])
    assert workbook.kernel_start_failures(report, notebooks) == [notebooks[1]]
    wrong = ("failure", "Cell outputs differ")
    report = _report(tmp_path, [("01_a.ipynb", 0, wrong), ("02_b.ipynb", 0, died)])
    assert workbook.kernel_start_failures(report, notebooks) is None          # a real failure: no second chance
    report = _report(tmp_path, [("01_a.ipynb", 0, None)])
    assert workbook.kernel_start_failures(report, notebooks) is None          # nothing to run again
    assert workbook.kernel_start_failures(tmp_path / "missing.xml", notebooks) is None
    report = _report(tmp_path, [("09_other.ipynb", 0, died)])
    assert workbook.kernel_start_failures(report, notebooks) is None          # not one of the notebooks run


def _recorded_unit_run(monkeypatch, ci, machine="x86_64"):
    """The pytest commands and environments ``test_unit`` runs (nothing is run)."""
    calls = []
    monkeypatch.setattr(workbook, "setup", lambda: None)
    monkeypatch.setattr(workbook, "STUDENT_EDITION", False)
    monkeypatch.setattr(workbook.platform, "machine", lambda: machine)
    monkeypatch.setenv("CI", "true" if ci else "")
    monkeypatch.setenv("WORKBOOK_JOBS", "2")
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "NPY_DISABLE_CPU_FEATURES", "NUMBA_CPU_NAME"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(workbook, "run", lambda cmd, env=None, check=True: calls.append(([str(c) for c in cmd], env)))
    workbook.test_unit()
    assert calls[0][0][1:4] == ["-m", "ruff", "check"]      # the linter runs first, once
    return calls[1:]


def test_ci_runs_the_unit_tests_again_on_each_lowered_cpu(monkeypatch):
    calls = _recorded_unit_run(monkeypatch, ci=True)
    assert len(calls) == 1 + len(workbook.CPU_PASSES)
    first, lowered = calls[0], calls[1:]
    assert "not cpu_independent" not in first[0] and "NPY_DISABLE_CPU_FEATURES" not in first[1]   # all, as the CPU is
    for (cmd, env), (_, variables) in zip(lowered, workbook.CPU_PASSES, strict=True):
        assert cmd[cmd.index("-m", 3) + 1] == "not cpu_independent" and cmd[-1] == "tests"
        assert {k: env[k] for k in variables} == variables and env["OPENBLAS_NUM_THREADS"] == "1"
        assert cmd[cmd.index("-W") + 1] == "error" and cmd[cmd.index("-n") + 1] == "2"
    assert lowered[-1][1]["NUMBA_CPU_NAME"] == "generic"
    assert "X86_V3" in lowered[-1][1]["NPY_DISABLE_CPU_FEATURES"]


def test_without_ci_or_off_x86_the_unit_tests_run_once(monkeypatch, capsys):
    assert len(_recorded_unit_run(monkeypatch, ci=False)) == 1
    assert len(_recorded_unit_run(monkeypatch, ci=True, machine="arm64")) == 1
    assert "only defined for x86-64, skipped on arm64" in capsys.readouterr().out


def test_the_marker_of_the_left_out_tests_is_registered():
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert '"%s: ' % workbook.CPU_INDEPENDENT in text


@pytest.mark.cpu_independent  # a file check and a message
def test_the_instructors_tasks_say_where_they_are_in_a_student_edition(tmp_path, monkeypatch):
    monkeypatch.setattr(workbook, "ROOT", tmp_path)
    monkeypatch.setattr(workbook, "setup", lambda: pytest.fail("set-up must not run when the tool is missing"))
    with pytest.raises(workbook.TaskError, match="instructor's tool: it is in the answer key"):
        workbook.TASKS["grade-all"](["submissions"])
