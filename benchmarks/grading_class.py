"""Grade a synthetic class of 20 submissions with ``grade-all`` and with the Gradescope autograder; check every score.

    .venv/bin/python benchmarks/grading_class.py [--jobs 2] [--keep DIR]

The 20 submissions (tools/synthetic_class.py: correct, wrong, empty, crashing, hanging in Python and in C,
a forcing conftest.py, edited tests, deleting files outside its folder, ...) each have a designed score. The script

1. builds the student edition, writes the class, grades it with ``grade_all`` (``--jobs`` workers) and compares
   every total with its design; checks that the file the deleting submission aims at is still there and that no
   zip member was written outside;
2. builds the Gradescope autograder zip, lays out ``/autograder`` in a temporary folder (``source/`` = the zip
   unpacked, ``submission/`` = the student's upload, ``results/``) and runs its ``run_autograder`` on each of the 20
   submissions in turn; the sum of ``results.json``'s test scores must equal ``grade_all``'s total;
3. grades the correct submission alone and reports the CPU seconds of its grading processes (target: <= 60 s).

Prints one line per submission and the wall times; exit status 1 when any score differs from its design.
(Windows: no Gradescope runs, and no CPU time of child processes.)
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile

try:
    import resource                       # POSIX: CPU time of finished child processes
except ImportError:                       # Windows
    resource = None

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
import grade_all  # noqa: E402
import gradescope  # noqa: E402
import grading_tree  # noqa: E402
import student  # noqa: E402
import synthetic_class  # noqa: E402

LIMITS = {"timeout_per_submission": 180, "test_limit": 60}   # as on Gradescope


def run_gradescope(autograder_zip: pathlib.Path, zips: list, work: pathlib.Path) -> dict:
    """{student: (sum of results.json's scores, seconds)} from the autograder run on each zip as the upload."""
    ag = work / "autograder"
    with zipfile.ZipFile(autograder_zip) as zf:
        zf.extractall(ag / "source")
    os.chmod(ag / "source" / "run_autograder", 0o755)
    env = dict(os.environ, AUTOGRADER_ROOT=str(ag), AUTOGRADER_PYTHON=sys.executable)
    out = {}
    for path in zips:
        for sub in ("submission", "results"):
            shutil.rmtree(ag / sub, ignore_errors=True)
            (ag / sub).mkdir()
        shutil.copy2(path, ag / "submission" / "submission.zip")
        start = time.perf_counter()
        subprocess.run(["bash", str(ag / "source" / "run_autograder")], env=env, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT, timeout=1800)
        data = json.loads((ag / "results" / "results.json").read_text(encoding="utf-8"))
        out[path.stem] = (sum(t["score"] for t in data["tests"]), time.perf_counter() - start)
    return out


def cpu_of_one(zip_path: pathlib.Path, tree: pathlib.Path) -> tuple[float, float, float]:
    """(CPU seconds of the grading processes, wall seconds, score) of grading one submission alone."""
    usage = (lambda: resource.getrusage(resource.RUSAGE_CHILDREN)) if resource else None
    before = usage() if usage else None
    start = time.perf_counter()
    result = grade_all.grade_submission(zip_path, tree, student.load_registry(), timeout=180)
    after = usage() if usage else None
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime) if usage else float("nan")
    return cpu, time.perf_counter() - start, result["total"]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--keep", type=pathlib.Path, default=None, help="keep the class and results here")
    args = parser.parse_args(argv)
    work = args.keep or pathlib.Path(tempfile.mkdtemp(prefix="grading-class-"))
    work.mkdir(parents=True, exist_ok=True)
    edition = student.build(work / "edition", quiet=True)
    design = synthetic_class.write_class(work / "class", edition)
    start = time.perf_counter()
    results = grade_all.grade_all(work / "class", work / "graded", jobs=args.jobs, **LIMITS)
    batch_wall = time.perf_counter() - start
    totals = {r["student"]: r["total"] for r in results}
    sentinel_kept = (work / "SENTINEL").exists()
    escaped = [p for p in (work.parent / "outside_grading.py", pathlib.Path("/tmp/absolute_grading.py")) if p.exists()]

    autograder = gradescope.build(work / "autograder.zip")
    start = time.perf_counter()
    if os.name == "nt":                    # run_autograder is a bash script (Gradescope runs Linux)
        print("Windows: the Gradescope runs are left out; its scores are taken as grade-all's")
        gs = {name: (total, 0.0) for name, total in totals.items()}
    else:
        gs = run_gradescope(autograder, sorted((work / "class").glob("*.zip")), work)
    gs_wall = time.perf_counter() - start

    bad = 0
    tree = grading_tree.build_grading_tree(work / "tree-for-cpu")
    cpu, wall_one, score_one = cpu_of_one(work / "class" / "correct.zip", tree)
    bad += score_one != design["correct"][0]

    print("%-12s %8s %8s %10s  %s" % ("student", "designed", "grade-all", "gradescope", "what"))
    for name, (designed, what) in design.items():
        ok = abs(totals[name] - designed) < 1e-9 and abs(gs[name][0] - designed) < 1e-9
        bad += not ok
        print("%-12s %8g %8g %10g  %s%s" % (name, designed, totals[name], gs[name][0], what,
                                             "" if ok else "   <-- differs"))
    print("grade-all: %d submissions in %.0f s wall on %d workers" % (len(totals), batch_wall, args.jobs))
    print("gradescope: %d runs of run_autograder in %.0f s wall (one after another; slowest %.0f s)"
          % (len(gs), gs_wall, max(s for _, s in gs.values())))
    print("one full correct submission alone: %g points, %.1f s CPU (target <= 60 s: ratio %.2f), %.1f s wall"
          % (score_one, cpu, cpu / 60, wall_one))
    print("deleting submission: target file kept: %s; zip members written outside: %d" % (sentinel_kept,
                                                                                          len(escaped)))
    print("every score as designed: %s" % (bad == 0 and sentinel_kept and not escaped))
    if args.keep is None:
        grading_tree.set_read_only(work, False)
        shutil.rmtree(work, ignore_errors=True)
    return 0 if bad == 0 and sentinel_kept and not escaped else 1


if __name__ == "__main__":
    sys.exit(main())
