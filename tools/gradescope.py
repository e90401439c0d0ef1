"""A Gradescope autograder for the exercises: build its zip, and grade one submission inside Gradescope's container.

    python tools/gradescope.py build [--out autograder.zip]      # = python tools/workbook.py gradescope
    python tools/gradescope.py run [--root /autograder]          # what the zip's run_autograder calls

Gradescope's format (its "autograder specifications"): the zip holds ``setup.sh`` (run once when the image is
built, as root, on the Ubuntu base image chosen in the assignment's settings) and ``run_autograder`` (run for each
submission, with the student's upload in ``/autograder/submission``); the zip's contents are in
``/autograder/source``; ``run_autograder`` writes ``/autograder/results/results.json``.

The zip built here holds:

- ``tree/``: the grading tree (tools/grading_tree.py: the student edition, the hidden tests and fixtures, the
  answer key's grade.py and registry); no answer-key body and no answer cell text is in it;
- ``grader/``: the grading code (grade_all.py, grading_tree.py, submission_files.py, submission.py, student.py,
  student_docs.py and this file), run with ``tree/`` as the root;
- ``requirements.txt`` (the workbook's lock), ``setup.sh`` (Python 3.12 of Ubuntu 24.04 in a venv, the lock, one
  run of the grader to fill numba's cache) and ``run_autograder``.

numba's on-disk cache is not in the zip (it holds this machine's CPU and Python); setup.sh compiles the kernels the
untouched edition's checks reach into the tree's cache, once; those only a solved exercise reaches are compiled
per submission (at most about 30 s of CPU on this machine).

``run``: the upload is the student's ``submission.zip`` (``make submission``) or its contents; a folder upload is
packed into a zip (regular files only: symbolic links are skipped) and graded exactly as ``grade_all`` grades a zip.
``results.json`` has one test per test group of each exercise (name "exercise: group", score, max_score, the
failed checks with expected and actual values and hints as output); groups of hidden tests have visibility
``after_published``. The top-level output gives the points of the visible groups and the reasons an exercise
could not be graded, never a hidden check's values. ``AUTOGRADER_ROOT`` (default ``/autograder``) and
``AUTOGRADER_PYTHON`` let the same files run in a folder laid out like it (tests/test_grade_all.py does).
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import shutil
import sys
import tempfile
import zipfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import grade_all  # noqa: E402
import grading_tree  # noqa: E402
import student  # noqa: E402

ROOT = student.ROOT
GRADER_FILES = ("grade_all.py", "grading_tree.py", "submission_files.py", "submission.py", "student.py",
                "student_docs.py", "gradescope.py")       # (grade_guard.py is in the grading tree, next to grade.py)
TIMEOUTS = {"timeout": 180, "test_limit": 60}      # seconds: one grading run, one check
MAX_UPLOAD_BYTES = 50_000_000

SETUP_SH = """#!/usr/bin/env bash
# Gradescope runs this once when it builds the autograder image (base image: Ubuntu 24.04, which has Python 3.12).
set -euo pipefail
apt-get update
apt-get install -y --no-install-recommends python3 python3-venv
python3 -m venv /autograder/venv
/autograder/venv/bin/python -m pip install --no-cache-dir -r /autograder/source/requirements.txt
# compile numba's kernels once into the grading tree's cache (every submission's copy starts from it)
cd /autograder/source/tree && PYTHONPATH=. /autograder/venv/bin/python tools/grade.py --student-ok > /dev/null || true
"""

RUN_AUTOGRADER = """#!/usr/bin/env bash
# Gradescope runs this for each submission: grades /autograder/submission into /autograder/results/results.json.
AG="${AUTOGRADER_ROOT:-/autograder}"
exec "${AUTOGRADER_PYTHON:-$AG/venv/bin/python}" "$AG/source/grader/gradescope.py" run --root "$AG"
"""


# ---------------------------------------------------------------------------------------------- build
def build(out: pathlib.Path, root=ROOT) -> pathlib.Path:
    """Write the autograder zip to ``out``; returns it."""
    root, out = pathlib.Path(root), pathlib.Path(out)
    work = pathlib.Path(tempfile.mkdtemp(prefix="gradescope-"))
    try:
        grading_tree.build_grading_tree(work / "tree", root)
        (work / "grader").mkdir()
        for name in GRADER_FILES:
            shutil.copy2(root / "tools" / name, work / "grader" / name)
        shutil.copy2(root / "environment.txt", work / "requirements.txt")
        for name, text in (("setup.sh", SETUP_SH), ("run_autograder", RUN_AUTOGRADER)):
            (work / name).write_text(text, encoding="utf-8", newline="\n")
        out.parent.mkdir(parents=True, exist_ok=True)
        partial = out.with_name(out.name + ".partial")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zf:
            for path in sorted(work.rglob("*")):
                if path.is_file() and "__pycache__" not in path.parts:    # (numba's cache is for this machine)
                    info = zipfile.ZipInfo.from_file(path, path.relative_to(work).as_posix())
                    if path.name in ("setup.sh", "run_autograder"):
                        info.external_attr = 0o100755 << 16
                    with open(path, "rb") as fh:
                        zf.writestr(info, fh.read(), zipfile.ZIP_DEFLATED)
        partial.replace(out)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return out


# ---------------------------------------------------------------------------------------------- run
def submission_zip(upload: pathlib.Path, scratch: pathlib.Path) -> pathlib.Path:
    """The zip to grade: the upload's only ``*.zip`` when it has one and no ``helpers/`` folder, else the upload's
    regular files (``*.py``, ``*.ipynb``; no symbolic link is followed) packed into ``scratch/submission.zip``."""
    zips = sorted(upload.glob("*.zip"))
    if len(zips) == 1 and not (upload / "helpers").is_dir() and not zips[0].is_symlink():
        return zips[0]
    packed, total = scratch / "submission.zip", 0
    with zipfile.ZipFile(packed, "w") as zf:
        for folder, dirs, files in os.walk(upload, followlinks=False):
            dirs[:] = [d for d in dirs if not os.path.islink(os.path.join(folder, d))]
            for name in files:
                path = pathlib.Path(folder) / name
                if path.is_symlink() or path.suffix not in (".py", ".ipynb") or not path.is_file():
                    continue
                total += path.stat().st_size
                if total > MAX_UPLOAD_BYTES:
                    break
                zf.write(path, path.relative_to(upload).as_posix())
    return packed


def results_json(result: dict, exercises: list) -> dict:
    """Gradescope's results: one test per test group; hidden groups ``after_published``."""
    tests, visible, visible_max = [], 0.0, 0.0
    for i, ex in enumerate(exercises, 1):
        for j, group in enumerate(result["groups"][ex["name"]], 1):
            tests.append({"name": "%s: %s" % (ex["name"], group["title"]), "number": "%d.%d" % (i, j),
                          "score": group["score"], "max_score": group["points"],
                          "output": group["output"] or "all checks passed",
                          "visibility": "after_published" if group["hidden"] else "visible"})
            if not group["hidden"]:
                visible, visible_max = visible + group["score"], visible_max + group["points"]
    lines = ["Points of the public checks: %g of %g. The hidden checks (%g points) are shown when the grades are "
             "published." % (visible, visible_max, result["possible"] - visible_max)]
    lines += ["%s: %s" % (name, why) for name, why in result["reasons"].items()]
    answers = result.get("answers") or []
    if answers:
        lines.append("Written answers (marked by hand): %d of %d answered." % (
            sum(a["status"] == "answered" for a in answers), len(answers)))
    return {"tests": tests, "output": "\n".join(lines), "stdout_visibility": "hidden",
            "execution_time": round(result.get("seconds", 0.0), 1)}


def run(ag_root: pathlib.Path, only=None) -> dict:
    """Grade ``ag_root/submission`` with the tree in ``ag_root/source/tree`` (the exercises ``only``, default all);
    write and return the results."""
    tree = ag_root / "source" / "tree"
    reg = student.load_registry(tree)
    out = ag_root / "results" / "results.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    scratch = pathlib.Path(tempfile.mkdtemp(prefix="upload-"))
    try:
        zip_path = submission_zip(ag_root / "submission", scratch)
        result = grade_all.grade_submission(zip_path, tree, reg, root=tree, only=only, **TIMEOUTS)
        data = results_json(result, [ex for ex in reg["exercise"] if not only or ex["name"] in only])
    except Exception as err:                   # noqa: BLE001  (Gradescope must get a results file)
        data = {"score": 0, "output": "The autograder could not grade this submission (%s: %s). Please tell the "
                                      "instructor." % (type(err).__name__, err), "tests": []}
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    out.write_text(json.dumps(data, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    return data


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="cmd", required=True)
    b = sub.add_parser("build", help="write the autograder zip")
    b.add_argument("--out", type=pathlib.Path, default=ROOT / "build" / "autograder.zip")
    r = sub.add_parser("run", help="grade /autograder/submission (inside Gradescope)")
    r.add_argument("--root", type=pathlib.Path, default=pathlib.Path(os.environ.get("AUTOGRADER_ROOT", "/autograder")))
    args = parser.parse_args(argv)
    if args.cmd == "build":
        try:
            path = build(args.out)
        except student.BuildError as err:
            print("error: %s" % err, file=sys.stderr)
            return 2
        print("wrote %s (%.1f MB): upload it as the assignment's autograder, base image Ubuntu 24.04"
              % (path, path.stat().st_size / 1e6))
        return 0
    data = run(args.root)
    print("graded: %g of %g" % (sum(t["score"] for t in data["tests"]), sum(t["max_score"] for t in data["tests"])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
