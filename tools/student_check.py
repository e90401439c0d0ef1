"""The CI check of the student edition (issue 16, part E); ``make test`` runs it with CI=true.

    python tools/student_check.py [--keep DIR]

1. builds the student edition into a temporary directory (``tools/student.py``, with its self-check), and a copy
   of it with one answer-key solution (``SOLUTION``, an exercise whose tests need no other exercise) put in;
2. grades the student edition with the answer key's interpreter and PYTHONPATH at the student tree (no second
   environment): expects ``exercises: 0 passed, N failed`` and ``other tests: K passed, 0 failed``;
3. grades the copy with the solution: expects exactly that exercise to pass (and the other tests still to pass);
4. grades the answer key's exercises (``--exercises-only``: its other tests are ``make test``'s unit tests, which
   ``CI=true make test`` runs just before): expects ``exercises: N passed, 0 failed``.
The three gradings run at the same time, in separate processes on independent trees.
Prints one line per step and ``student edition check: N passed, M failed``; exit status 1 on any failure.
"""
from __future__ import annotations

import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import student  # noqa: E402

ROOT = student.ROOT
SOLUTION = "lab8_2a_individual_compatibility"
SUMMARY = re.compile(r"^(exercises|other tests): (\d+) passed, (\d+) failed$", re.M)


def start_grading(tree: pathlib.Path, log: pathlib.Path, *args):
    """Start tree's grader with this interpreter, its output going to the file ``log`` (a file, not a pipe:
    graders run side by side and none may block on a full pipe). ``finish_grading`` collects it."""
    env = dict(os.environ, PYTHONPATH=str(tree), PYTHONIOENCODING="utf-8")     # the log is read as UTF-8
    with open(log, "w", encoding="utf-8") as out:
        process = subprocess.Popen([sys.executable, str(tree / "tools" / "grade.py")] + list(args), cwd=str(tree),
                                   env=env, stdout=out, stderr=subprocess.STDOUT)
    process.log = log
    return process


def finish_grading(process: subprocess.Popen):
    """Wait for a grader; returns (its output, {"exercises": (p, f), "other tests": (p, f)})."""
    process.wait()
    output = process.log.read_text(encoding="utf-8", errors="replace")
    counts = {m.group(1): (int(m.group(2)), int(m.group(3))) for m in SUMMARY.finditer(output)}
    return output, counts


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    keep = pathlib.Path(argv[argv.index("--keep") + 1]) if "--keep" in argv else None
    start = time.perf_counter()
    results = []

    def check(label, ok, output=""):
        results.append(ok)
        print("%s: %s" % ("ok    " if ok else "FAILED", label), flush=True)
        if not ok and output:
            print(output[-4000:], flush=True)

    n = len(student.load_registry()["exercise"])
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="student-edition-"))
    tree = keep or tmp / "student"
    graders = []
    try:
        student.build(tree, quiet=True)
        check("the student edition builds and passes its self-check (%d exercises)" % n, True)
        solved = tmp / "student-with-solution"
        shutil.copytree(tree, solved, ignore=shutil.ignore_patterns("__pycache__", ".pytest_cache"))
        student.copy_solution(solved, SOLUTION)
        graders = [start_grading(tree, tmp / "student.log"), start_grading(solved, tmp / "solved.log"),
                   start_grading(ROOT, tmp / "answer-key.log", "--exercises-only")]
        out, counts = finish_grading(graders[0])
        check("student edition: exercises: %s passed, %s failed (expected 0, %d); other tests: %s passed, %s failed"
              % (counts.get("exercises", ("?", "?")) + (n,) + counts.get("other tests", ("?", "?"))),
              counts.get("exercises") == (0, n) and counts.get("other tests", (0, 1))[1] == 0
              and counts["other tests"][0] > 0, out)
        out, counts = finish_grading(graders[1])
        passed = re.findall(r"^(\w+)\s+passed$", out, re.M)
        check("student edition with the answer key's %s: exactly that exercise passes" % SOLUTION,
              passed == [SOLUTION] and counts.get("exercises") == (1, n - 1)
              and counts.get("other tests", (0, 1))[1] == 0, out)
        out, counts = finish_grading(graders[2])
        check("answer key: exercises: %d passed, 0 failed" % n, counts.get("exercises") == (n, 0), out)
    except student.BuildError as err:
        check("the student edition builds: %s" % err, False)
    finally:
        for process in graders:                                      # interrupted: no grader left behind
            if process.poll() is None:
                process.kill()
                process.wait()
        if keep is None:
            shutil.rmtree(tmp, ignore_errors=True)
    print("student edition check took %.0f s" % (time.perf_counter() - start))
    print("student edition check: %d passed, %d failed" % (sum(results), len(results) - sum(results)))
    return 0 if all(results) else 1


if __name__ == "__main__":
    sys.exit(main())
