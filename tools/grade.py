"""Grade the exercises: run each exercise's own tests and say what failed and why (``make grade [EX=name]``).

    python tools/grade.py [NAME ...] [--student-ok] [--status FILE] [--all] [--timeout S] [--progress FILE]
                          [--verbose]
    python tools/grade.py NAME --isolate        # the answer key: every OTHER exercise's targets raise

An exercise ``NAME`` is graded by ``tests/exercises/test_NAME.py`` (the public tests, shipped with the student
edition) and, where present, ``tests/exercises/test_NAME_hidden.py`` (the instructor's value checks, only in the
answer key). Those tests call only that exercise and code that is not an exercise (inputs other exercises would
produce come from recorded fixtures), so every exercise is graded on its own, in seconds. Output, per exercise:

    lab8_2a_individual_compatibility   passed    (6 checks)
    lab8_2c_joint_compatibility        FAILED    2 of 7 checks failed
      ✗ the surprisal with nothing associated (test_nothing_associated)
          expected: 12.0
          actual:   0.0
        hint: with no pairing every landmark is unassociated and pays the surprisal s_U.
    l09_jcbb                           not written yet

then ``exercises: N passed, M failed``. Hints come from the registry (``tools/exercises.toml``, ``hints``: one per
test function). Exit status: 0 when every graded exercise passed, else 1; with ``--student-ok`` (the student
edition's ``make test``) 0 unless the grading itself broke. ``--status FILE`` writes the passed exercises and each
test's outcome as JSON (``{"passed": [NAME, ...], "tests": {nodeid: "passed" | "failed" | "skipped"}}``); ``--all``
prints every failed check (the instructor's feedback) instead of the first three; ``--timeout S`` is the time limit
of one check (default 120 s; pytest-timeout: a check that runs longer fails with "time limit" and the rest of its
exercise is skipped); ``--verbose`` shows pytest's own output. ``--progress FILE`` (the instructor's grader,
tools/grading_tree.py) appends one JSON line per event as it happens (``{"collected": [nodeid, ...]}``, ``{"start":
nodeid, "time": t}``, ``{"done": nodeid, "outcome", "title", "text"}``, ``{"finished": true, "passed": [...]}``):
when the grader kills a run that is stuck (in C code no time limit inside the process can stop), the file says
which check it was and which exercises were graded before it.
``--isolate`` (one exercise, in the answer key) first swaps the code
of every other exercise's target functions for a stub that raises ``ExerciseNotImplemented``, as the student
edition does: the exercise's tests must pass anyway (the check that they need no other exercise).
"""
from __future__ import annotations

import io
import json
import os
import pathlib
import re
import sys
import time
import tomllib
from contextlib import redirect_stderr, redirect_stdout

ROOT = pathlib.Path(__file__).resolve().parents[1]
TESTS = pathlib.Path("tests") / "exercises"
MAX_LINES = 14                      # of one failure's text
TEST_TIME_LIMIT = 120.0             # seconds per check (--timeout)


def load(root=ROOT) -> dict:
    with open(pathlib.Path(root) / "tools" / "exercises.toml", "rb") as fh:
        return tomllib.load(fh)


def test_files(name: str, root=ROOT) -> list[pathlib.Path]:
    """The test files of exercise ``name`` present in the tree at ``root`` (public first, then hidden)."""
    files = [TESTS / ("test_%s.py" % name), TESTS / ("test_%s_hidden.py" % name)]
    return [f for f in files if (pathlib.Path(root) / f).exists()]


def exercise_of(nodeid: str) -> str:
    """``tests/exercises/test_NAME[_hidden].py::...`` → NAME."""
    stem = pathlib.PurePosixPath(nodeid.split("::")[0]).stem
    return re.sub(r"_hidden$", "", stem[len("test_"):])


class Collector:
    """pytest plugin: each test's outcome and, for a failure, the text a student can act on."""

    def __init__(self, progress=None):
        self.outcome, self.failure, self.doc, self.errors = {}, {}, {}, []
        self.time_limit = set()                 # exercises with a check that hit the time limit
        self.progress = open(progress, "a", encoding="utf-8") if progress else None   # noqa: SIM115 (kept open)

    def log(self, **entry):
        """One line of JSON in the --progress file, flushed at once (the grader reads it after a kill)."""
        if self.progress:
            self.progress.write(json.dumps(entry) + "\n")
            self.progress.flush()

    def pytest_runtest_logstart(self, nodeid, location):
        self.log(start=nodeid, time=time.time())

    def pytest_runtest_logfinish(self, nodeid, location):
        outcome = self.outcome.get(nodeid, "failed")
        self.log(done=nodeid, outcome=outcome, title=self.doc.get(nodeid, ""),
                 text=self.failure.get(nodeid, "failed") if outcome == "failed" else "")

    def pytest_runtest_setup(self, item):
        if exercise_of(item.nodeid) in self.time_limit:     # one endless loop costs one time limit, not one per check
            import pytest

            pytest.skip("not run: an earlier check of this exercise hit the time limit")

    def pytest_collection_modifyitems(self, session, config, items):
        for item in items:
            doc = (getattr(item, "function", None).__doc__ or "") if hasattr(item, "function") else ""
            self.doc[item.nodeid] = " ".join(doc.split()).split(". ")[0].rstrip(".")
        self.log(collected=[item.nodeid for item in items])

    def pytest_collectreport(self, report):
        if report.failed:
            self.errors.append((report.nodeid, _failure_text(report)))

    def pytest_runtest_logreport(self, report):
        if report.failed:
            self.outcome[report.nodeid] = "failed"
            self.failure.setdefault(report.nodeid, _failure_text(report))
            if self.failure[report.nodeid].startswith("time limit"):
                self.time_limit.add(exercise_of(report.nodeid))
        elif report.when == "call" or report.skipped:
            self.outcome.setdefault(report.nodeid, "skipped" if report.skipped else "passed")


def _failure_text(report) -> str:
    """The failure as the student should read it: our check's message (what / given / expected / actual), or the
    exception the student's code raised with the line of helpers/ it came from; hypothesis's example after it."""
    text = getattr(report, "longreprtext", "") or str(getattr(report, "longrepr", ""))
    crash = getattr(getattr(report, "longrepr", None), "reprcrash", None)
    message = crash.message if crash is not None else text.strip().splitlines()[-1:] and text.strip().splitlines()[-1]
    stub = re.search(r"exercise (\w+) is not implemented yet", text)
    limit = re.search(r"Timeout \(>([\d.]+)s\) from pytest-timeout", text)
    if limit:
        return "time limit: this check ran longer than %g s (an endless loop, or far too slow)" % float(limit.group(1))
    if stub:
        return "not written yet: exercise %s raises ExerciseNotImplemented" % stub.group(1)
    if message.startswith("AssertionError: check:"):
        body = message[len("AssertionError: "):]
    else:                                                    # the student's code raised: where, and what
        where = [ln.strip().rsplit(":", 1)[0] for ln in text.splitlines()
                 if re.match(r"^\s*(helpers|tests)[/\\].*:\d+: ", ln)]
        body = message + ("\n  raised at %s" % " <- called from ".join(where[::-1][:3]) if where else "")
    example = re.search(r"^Falsifying example:.*?(?=^\S|\Z)", text, re.M | re.S)
    if example:
        body += "\n  " + example.group(0).strip().replace("\n", "\n  ")
    lines = body.splitlines()
    return "\n".join(lines[:MAX_LINES] + (["  ..."] if len(lines) > MAX_LINES else []))


def isolate(keep: str, exercises) -> int:
    """Swap the code of every target of the exercises other than ``keep`` for a raising stub; returns how many.
    The function objects stay (references imported elsewhere see the stub too)."""
    import importlib

    count = 0
    for ex in exercises:
        if ex["name"] == keep:
            continue
        for target in ex["targets"]:
            module, _, qualname = target.partition(":")
            owner = importlib.import_module(module)
            *path, attr = qualname.split(".")
            for part in path:
                owner = getattr(owner, part)
            func = owner.__dict__[attr] if isinstance(owner, type) else getattr(owner, attr)
            namespace = {}
            exec("def stub(*args, **kwargs):\n    raise __import__('helpers.exercises', fromlist=['_'])"
                 ".ExerciseNotImplemented(%r, 'the isolation check')" % ex["name"], namespace)
            func.__code__ = namespace["stub"].__code__
            count += 1
    return count


def run_tests(files, collector, root=ROOT, verbose=False, time_limit=TEST_TIME_LIMIT) -> int:
    import pytest

    os.chdir(root)
    sys.path.insert(0, str(root))
    args = ["-q", "-p", "no:cacheprovider", "-p", "no:randomly", "--tb=long", "-W", "error",
            "--continue-on-collection-errors", "-o", "addopts=", "--timeout=%g" % time_limit] + [str(f) for f in files]
    if verbose:
        return pytest.main(args, plugins=[collector])
    buffer = io.StringIO()
    with redirect_stdout(buffer), redirect_stderr(buffer):
        code = pytest.main(args, plugins=[collector])
    if code not in (0, 1, 5):                                 # interrupted, internal or usage error
        sys.stdout.write(buffer.getvalue()[-6000:])
    return code


def report(collector, exercises, shown=3) -> list[str]:
    """Print one block per exercise (its first ``shown`` failed checks; None: all) and the summary line; returns the
    names of the passed exercises. A hidden test's check is marked "[hidden]"."""
    width = max(len(ex["name"]) for ex in exercises) + 2
    by_ex = {ex["name"]: [] for ex in exercises}
    for nodeid, outcome in collector.outcome.items():
        by_ex.setdefault(exercise_of(nodeid), []).append((nodeid, outcome))
    for nodeid, text in collector.errors:
        by_ex.setdefault(exercise_of(nodeid), []).append((nodeid, "failed"))
        collector.failure[nodeid] = "the test file does not import: " + text
    passed = []
    for ex in exercises:
        results = by_ex[ex["name"]]
        failed = [n for n, o in results if o == "failed"]
        ran = [n for n, o in results if o != "skipped"]
        name = ex["name"].ljust(width)
        if ran and not failed:
            passed.append(ex["name"])
            print("%s passed    (%d checks)" % (name, len(ran)), flush=True)
            continue
        if not ran:
            print("%s FAILED    no test of this exercise ran" % name)
            continue
        texts = [collector.failure.get(n, "failed") for n in failed]
        if all(t.startswith("not written yet") for t in texts):
            print("%s not written yet: write %s (task: EXERCISES.md, section %s)" % (
                name, ", ".join(t.split(":")[1] for t in ex["targets"]), ex["name"]))
            continue
        print("%s FAILED    %d of %d checks failed" % (name, len(failed), len(ran)))
        hints = ex.get("hints", {})
        for nodeid in failed[:shown]:
            func = nodeid.split("::")[-1].split("[")[0]
            title = collector.doc.get(nodeid) or func
            hidden = "[hidden] " if "_hidden.py::" in nodeid else ""
            print("  ✗ %s%s (%s)" % (hidden, title, nodeid.split("::", 1)[-1]))
            print("      " + collector.failure.get(nodeid, "failed").replace("\n", "\n      "))
            if func in hints:
                print("    hint: " + " ".join(hints[func].split()))
        if ex["name"] in collector.time_limit:
            print("  (after the time limit the other %d checks of this exercise were not run)"
                  % sum(1 for _, o in results if o == "skipped"))
        if shown is not None and len(failed) > shown:
            print("  ... and %d more (make grade EX=%s, or tools/grade.py %s --verbose)"
                  % (len(failed) - shown, ex["name"], ex["name"]))
    print("exercises: %d passed, %d failed" % (len(passed), len(exercises) - len(passed)), flush=True)
    return passed


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    status_file = argv.pop(argv.index("--status") + 1) if "--status" in argv else None
    progress = argv.pop(argv.index("--progress") + 1) if "--progress" in argv else None
    try:
        time_limit = float(argv.pop(argv.index("--timeout") + 1)) if "--timeout" in argv else TEST_TIME_LIMIT
    except (IndexError, ValueError):
        print("--timeout takes the time limit of one check in seconds, e.g. --timeout 60")
        return 2
    names = [a for a in argv if not a.startswith("--")]
    exercises = load()["exercise"]
    known = [ex["name"] for ex in exercises]
    unknown = [n for n in names if n not in known]
    if unknown:
        print("unknown exercise %s; the exercises are: %s" % (", ".join(unknown), ", ".join(known)))
        return 2
    graded = [ex for ex in exercises if not names or ex["name"] in names]
    files = [f for ex in graded for f in test_files(ex["name"])]
    collector = Collector(progress)
    if "--isolate" in argv:
        if len(graded) != 1:
            print("--isolate grades one exercise at a time")
            return 2
        sys.path.insert(0, str(ROOT))
        print("isolation: %d targets of other exercises raise" % isolate(graded[0]["name"], exercises))
    code = run_tests(files, collector, verbose="--verbose" in argv, time_limit=time_limit) if files else 5
    passed = report(collector, graded, shown=None if "--all" in argv else 3)
    collector.log(finished=True, passed=passed)
    if status_file:
        tests = dict(collector.outcome)
        tests.update({nodeid: "failed" for nodeid, _ in collector.errors})
        pathlib.Path(status_file).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(status_file).write_text(json.dumps({"passed": passed, "tests": tests}), encoding="utf-8")
    if code not in (0, 1, 5):
        return 1
    if "--student-ok" in argv:
        return 0
    return 0 if len(passed) == len(graded) else 1


if __name__ == "__main__":
    sys.exit(main())
