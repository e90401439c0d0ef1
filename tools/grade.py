"""Grade the exercises: run the unit tests once and report per exercise (``make grade``, ``make grade EX=name``).

    python tools/grade.py [NAME] [--student-ok] [--exercises-only] [--status FILE] [--verbose]

Runs pytest in-process over ``tests/`` (of the tree this file is in), maps every test to its exercise through
``tools/exercises.toml`` (node ids or node-id prefixes) and prints one line per exercise,

    lab8_2a_individual_compatibility    passed
    lab8_2c_joint_compatibility         FAILED  test_joint_compatibility_published: ExerciseNotImplemented: ...

then exactly two summary lines: ``exercises: N passed, M failed`` and ``other tests: K passed, L failed`` (the
tests of no exercise). With NAME only that exercise is graded (the other tests still run and are reported).
An exercise passes when all its tests pass (and at least one ran). In the student edition (a tree with
EXERCISES.md) the registry's answer-key-only tests are not run.

Exit status: 0 when every graded exercise and every other test passed, else 1; with ``--student-ok`` (the
student edition's ``make test``) 0 whenever the other tests passed, so unfinished exercises do not fail it.
``--status FILE`` writes the names of the passed exercises as JSON (the student ``make test`` picks notebooks
with it); ``--exercises-only`` runs only the tests the registry lists (the verdicts of a tree whose tests all
pass, such as the answer key's, without running the other tests again); ``--verbose`` shows pytest's own output.
"""
from __future__ import annotations

import io
import json
import os
import pathlib
import re
import sys
import tomllib
from contextlib import redirect_stderr, redirect_stdout

ROOT = pathlib.Path(__file__).resolve().parents[1]
REGISTRY = ROOT / "tools" / "exercises.toml"


def load(root=ROOT):
    with open(pathlib.Path(root) / "tools" / "exercises.toml", "rb") as fh:
        return tomllib.load(fh)


def is_student_edition(root=ROOT) -> bool:
    return (pathlib.Path(root) / "EXERCISES.md").exists()


def matches(nodeid: str, pattern: str) -> bool:
    """A registry entry names a test (with or without parameters) or a node-id prefix."""
    return nodeid == pattern or nodeid.startswith(pattern) or nodeid.split("[")[0] == pattern


def exercise_of(nodeid: str, exercises) -> str | None:
    for ex in exercises:
        if any(matches(nodeid, p) for p in ex["tests"]):
            return ex["name"]
    return None


class Collector:
    """pytest plugin: deselects what is not graded and records each test's outcome and first failure."""

    def __init__(self, exercises, only=None, skip=(), exercises_only=False):
        self.exercises, self.only, self.skip = exercises, only, tuple(skip)
        self.exercises_only = exercises_only
        self.outcome, self.failure, self.errors = {}, {}, []

    def pytest_collection_modifyitems(self, session, config, items):
        keep, drop = [], []
        for item in items:
            ex = exercise_of(item.nodeid, self.exercises)
            skipped = any(matches(item.nodeid, p) for p in self.skip)
            ungraded = (self.only and ex not in (None, self.only)) or (self.exercises_only and ex is None)
            (drop if skipped or ungraded else keep).append(item)
        if drop:
            config.hook.pytest_deselected(items=drop)
        items[:] = keep

    def pytest_collectreport(self, report):
        if report.failed:
            self.errors.append("%s: %s" % (report.nodeid or "collection", _first_line(report)))

    def pytest_runtest_logreport(self, report):
        if report.failed:
            self.outcome[report.nodeid] = "failed"
            self.failure.setdefault(report.nodeid, _first_line(report))
        elif report.when == "call" or report.skipped:
            self.outcome.setdefault(report.nodeid, "skipped" if report.skipped else "passed")


def _first_line(report) -> str:
    crash = getattr(getattr(report, "longrepr", None), "reprcrash", None)
    text = crash.message if crash is not None else str(getattr(report, "longrepr", "") or "")
    line = next((ln.strip() for ln in text.splitlines() if ln.strip()), "failed")
    if "is not implemented yet" in line:           # an exercise stub: name it, drop the advice
        line = "ExerciseNotImplemented: " + line.split("ExerciseNotImplemented: ", 1)[-1].split(". Its task")[0]
    return line if len(line) <= 160 else line[:157] + "..."


def run_tests(collector, root=ROOT, verbose=False) -> int:
    import pytest

    os.chdir(root)
    sys.path.insert(0, str(root))
    args = ["-q", "-p", "no:cacheprovider", "-p", "no:randomly", "--tb=short", "tests"]
    buffer = io.StringIO()
    if verbose:
        return pytest.main(args, plugins=[collector])
    with redirect_stdout(buffer), redirect_stderr(buffer):
        code = pytest.main(args, plugins=[collector])
    if code not in (0, 1, 5) or collector.errors:      # interrupted, internal or usage error, collection errors
        sys.stdout.write(buffer.getvalue()[-6000:])
    return code


def stub_named(failure: str, exercises) -> str | None:
    """The exercise whose stub a test's failure line names (``ExerciseNotImplemented: exercise NAME …``), if any.

    A test that is not listed in the registry but stops at an exercise's stub grades with that exercise: it
    cannot pass before the exercise is done, and it passes (as an other test's would) once it is."""
    match = re.search(r"ExerciseNotImplemented: exercise (\w+)", failure)
    names = {ex["name"] for ex in exercises}
    return match.group(1) if match and match.group(1) in names else None


def report(collector, exercises, only=None):
    """Print the per-exercise lines and the two summary lines; returns (ex_passed, ex_failed, other_p, other_f)."""
    graded = [ex for ex in exercises if only in (None, ex["name"])]
    width = max(len(ex["name"]) for ex in graded) + 2
    by_ex = {ex["name"]: [] for ex in graded}
    other = []
    for nodeid, outcome in collector.outcome.items():
        ex = exercise_of(nodeid, exercises) or stub_named(collector.failure.get(nodeid, ""), exercises)
        (by_ex[ex] if ex in by_ex else other if ex is None else []).append((nodeid, outcome))
    status = {}
    for ex in graded:
        results = sorted(by_ex[ex["name"]])
        failed = [n for n, o in results if o == "failed"]
        ran = [n for n, o in results if o != "skipped"]
        status[ex["name"]] = bool(ran) and not failed
        if status[ex["name"]]:
            print("%s passed" % ex["name"].ljust(width))
            continue
        first = failed[0] if failed else None
        why = ("%s: %s" % (first.split("::", 1)[-1], collector.failure.get(first, "failed"))) if first \
            else "no test of this exercise ran (check its tests in tools/exercises.toml)"
        print("%s FAILED  %s" % (ex["name"].ljust(width), why))
    for ex in graded:
        missing = [n for n in ex["needs"] if status.get(n) is False]
        if not status[ex["name"]] and missing:
            print("  (%s also needs: %s)" % (ex["name"], ", ".join(missing)))
    other_failed = sorted(n for n, o in other if o == "failed")
    for nodeid in other_failed[:20]:
        print("other test FAILED  %s: %s" % (nodeid, collector.failure.get(nodeid, "failed")))
    if len(other_failed) > 20:
        print("  ... and %d more other tests failed" % (len(other_failed) - 20))
    for err in collector.errors:
        print("collection error: %s" % err)
    n_pass = sum(status.values())
    o_pass = sum(1 for _, o in other if o == "passed")
    o_fail = sum(1 for _, o in other if o == "failed") + len(collector.errors)
    print("exercises: %d passed, %d failed" % (n_pass, len(graded) - n_pass))
    print("other tests: %d passed, %d failed" % (o_pass, o_fail))
    return n_pass, len(graded) - n_pass, o_pass, o_fail, sorted(n for n, ok in status.items() if ok)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    student_ok = "--student-ok" in argv
    verbose = "--verbose" in argv
    status_file = argv.pop(argv.index("--status") + 1) if "--status" in argv else None
    names = [a for a in argv if not a.startswith("--")]
    registry = load()
    exercises = registry["exercise"]
    for ex in exercises:
        ex.setdefault("needs", [])
    only = names[0] if names else None
    if only is not None and only not in {ex["name"] for ex in exercises}:
        print("unknown exercise %r; the exercises are: %s" % (only, ", ".join(ex["name"] for ex in exercises)))
        return 2
    skip = registry.get("edition", {}).get("answer_key_only_tests", []) if is_student_edition() else []
    collector = Collector(exercises, only, skip, exercises_only="--exercises-only" in argv)
    code = run_tests(collector, verbose=verbose)
    _, ex_failed, _, other_failed, passed = report(collector, exercises, only)
    if status_file:
        pathlib.Path(status_file).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(status_file).write_text(json.dumps({"passed": passed}), encoding="utf-8")
    if code not in (0, 1, 5):
        return 1
    if student_ok:
        return 1 if other_failed else 0
    return 1 if (ex_failed or other_failed) else 0


if __name__ == "__main__":
    sys.exit(main())
