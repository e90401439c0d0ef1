"""The CI check of the student edition (issue 37, parts A and C); ``CI=true make test`` runs it.

    python tools/student_check.py [--keep DIR] [--jobs N] [--no-notebooks]

1. builds the student edition into a temporary directory (``tools/student.py``: its self-check proves that no
   solution body, no hidden test or fixture, no answer cell and no check cell reaches it);
2. grades the untouched edition (every exercise must fail: ``exercises: 0 passed``) and, for EVERY exercise, a
   copy of the edition with only that exercise's answer-key solution put in: exactly that exercise must pass
   (its checks call nothing else, so it stands alone);
3. grades the answer key (public and hidden tests): every exercise passes;
4. runs every notebook (nbval in lax mode: every cell runs without error) in a copy of the edition with only the
   exercises that notebook uses solved (``notebooks`` in tools/exercises.toml): a notebook needs nothing else.
Graders and notebook runs go on ``--jobs`` workers (default 2), each in its own process and tree, with this
interpreter and PYTHONPATH at the tree (no second environment). Prints one line per step and
``student edition check: N passed, M failed``; exit status 1 on any failure.
"""
from __future__ import annotations

import concurrent.futures
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
SUMMARY = re.compile(r"^exercises: (\d+) passed, (\d+) failed$", re.M)
PASSED = re.compile(r"^(\w+)\s+passed\s", re.M)


def run(tree: pathlib.Path, args: list, timeout: float = 900) -> tuple[int, str]:
    """Run ``python args`` in ``tree`` with PYTHONPATH at it; (exit status, output)."""
    env = dict(os.environ, PYTHONPATH=str(tree), PYTHONIOENCODING="utf-8", MPLBACKEND="Agg")
    try:
        out = subprocess.run([sys.executable] + args, cwd=str(tree), env=env, capture_output=True, text=True,
                             encoding="utf-8", errors="replace", timeout=timeout)
        return out.returncode, out.stdout + out.stderr
    except subprocess.TimeoutExpired as err:
        return -1, "timed out after %.0f s\n%s" % (timeout, err.stdout or "")


def solved_copy(edition: pathlib.Path, dest: pathlib.Path, names) -> pathlib.Path:
    shutil.copytree(edition, dest, ignore=shutil.ignore_patterns("__pycache__", ".pytest_cache", "figures"))
    for name in names:
        student.copy_solution(dest, name)
    return dest


def grade_job(edition, tmp, name):
    """Grade a copy of the edition with the solution of ``name`` (None: untouched); (label, ok, output)."""
    tree = edition if name is None else solved_copy(edition, tmp / ("solved-" + name), [name])
    code, out = run(tree, ["tools/grade.py"])
    passed = PASSED.findall(out)
    expected = [] if name is None else [name]
    label = ("the untouched edition: no exercise passes" if name is None
             else "the edition with only %s solved: exactly it passes" % name)
    ok = passed == expected and SUMMARY.search(out) is not None
    if name is not None:
        shutil.rmtree(tree, ignore_errors=True)
    return label + ("" if ok else " (passed: %s)" % (passed or "none")), ok, out


def notebook_job(edition, tmp, names, notebooks):
    """Run ``notebooks`` (nbval, lax) in a copy of the edition with exactly ``names`` solved."""
    tree = solved_copy(edition, tmp / ("nb-" + "-".join(notebooks[0:1])), sorted(names))
    code, out = run(tree, ["-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:randomly", "-o", "addopts=",
                           "--nbval-lax", "--nbval-current-env", "--nbval-cell-timeout", "300"]
                    + ["notebooks/%s.ipynb" % n for n in notebooks], timeout=1800)
    shutil.rmtree(tree, ignore_errors=True)
    solved = "only %s solved" % ", ".join(sorted(names)) if names else "no exercise solved"
    label = "notebooks %s run with %s" % (", ".join(n.split("_")[0] for n in notebooks), solved)
    return label, code == 0, out


def notebook_sets(reg: dict, edition: pathlib.Path) -> dict:
    """{frozenset of exercises: [notebook stems]} for every notebook of the edition."""
    uses = {}
    for ex in reg["exercise"]:
        for stem in ex["notebooks"]:
            uses.setdefault(stem, set()).add(ex["name"])
    sets = {}
    for path in sorted((edition / "notebooks").glob("*.ipynb")):
        sets.setdefault(frozenset(uses.get(path.stem, ())), []).append(path.stem)
    return sets


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    unknown = [a for a in argv if a.startswith("-") and a not in ("--keep", "--jobs", "--no-notebooks")]
    if unknown or "--keep" in argv[-1:] or "--jobs" in argv[-1:]:
        print(__doc__.strip().splitlines()[2].strip())      # the usage line (-h, --help and unknown options)
        return 0 if unknown in (["-h"], ["--help"]) else 2
    keep = pathlib.Path(argv[argv.index("--keep") + 1]) if "--keep" in argv else None
    jobs = int(argv[argv.index("--jobs") + 1]) if "--jobs" in argv else 2
    start = time.perf_counter()
    results = []

    def check(label, ok, output=""):
        results.append(ok)
        print("%s: %s" % ("ok    " if ok else "FAILED", label), flush=True)
        if not ok and output:
            print(output[-4000:], flush=True)

    reg = student.load_registry()
    names = [ex["name"] for ex in reg["exercise"]]
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="student-edition-"))
    edition = keep or tmp / "student"
    try:
        student.build(edition, quiet=True)
        check("the student edition builds and passes its self-check (%d exercises)" % len(names), True)
        with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
            futures = [pool.submit(run, ROOT, ["tools/grade.py"])]
            futures += [pool.submit(grade_job, edition, tmp, n) for n in [None] + names]
            if "--no-notebooks" not in argv:
                sets = notebook_sets(reg, edition)
                futures += [pool.submit(notebook_job, edition, tmp, s, nbs) for s, nbs in
                            sorted(sets.items(), key=lambda kv: -len(kv[1]))]
            code, out = futures[0].result()
            check("the answer key: every exercise passes its public and hidden tests",
                  code == 0 and PASSED.findall(out) == names, out)
            for future in futures[1:]:
                check(*future.result())
    except student.BuildError as err:
        check("the student edition builds: %s" % err, False)
    finally:
        if keep is None:
            shutil.rmtree(tmp, ignore_errors=True)
    print("student edition check took %.0f s" % (time.perf_counter() - start))
    print("student edition check: %d passed, %d failed" % (sum(results), len(results) - sum(results)))
    return 0 if all(results) else 1


if __name__ == "__main__":
    sys.exit(main())
