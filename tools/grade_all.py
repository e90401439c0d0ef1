"""Grade a class: every submission zip in a folder, inside a clean copy of the answer key's grading tree.

    python tools/grade_all.py SUBMISSIONS_DIR [--out DIR] [--jobs N] [--timeout S] [--only EX ...]

A submission is ``<student id>.zip`` (``make submission``: the module files that hold exercise targets, at their
repository-relative paths, and ``notebooks/*.ipynb``). Grading one submission:

1. the grading tree is built ONCE per batch: the student edition built from the answer key (tools/student.py), plus
   the answer key's hidden tests and hidden fixtures, its ``tools/grade.py`` and ``tools/exercises.toml``;
2. per submission, a copy of that tree receives ONLY the student's work: from the zip, the module files that hold
   exercise targets are read as text (never imported, never extracted; a path with ``..`` or an absolute path is
   ignored), parsed with ``ast``, and each target function's body is written into the tree's stub, with the
   module-level helper functions the student ADDED to that file (names the answer key's module does not define).
   Nothing else from the zip is used: no ``tests/``, ``conftest.py``, ``tools/`` or any other file;
3. ``tools/grade.py`` (the answer key's) runs in the copy in its own process (this interpreter, PYTHONPATH at the
   copy, its own session: killed whole at the limit), with a time limit per submission and its output capped;
   when that run hangs or dies before reporting, each exercise runs again alone with a time limit per exercise,
   so the exercise that hangs scores 0 with "time limit" and the others are graded;
4. ``OUT/grades.csv`` gets one row per student (points per exercise, total), ``OUT/feedback/<student>.txt`` the
   grader's text for that student and ``OUT/answers/<student>.json`` the written answers (the ``student-answer``
   cells of the submitted notebooks, matched by the answer key's answer cell ids) for marking by hand.

A file that is not a zip, lacks a module file or does not parse scores 0 for the exercises it affects, with the
reason in the feedback; the batch goes on. Points: ``points`` of the exercise in the registry, else 1.
TODO (issue 38, C): points per test group and partial credit (needs ``groups`` in the registry and per-test
outcomes from tools/grade.py); a time limit per TEST (needs pytest-timeout in the environment, or a hook in
tools/grade.py); every failed check in the feedback (tools/grade.py shows the first three).
Trust: the student's function bodies run in the grading process, as in any autograder; they cannot bring files,
but code that deliberately forges the grader's output from inside the process is not prevented here (the
Gradescope container of part D is the stronger sandbox).
"""
from __future__ import annotations

import argparse
import ast
import concurrent.futures
import csv
import json
import os
import pathlib
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import zipfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import student  # noqa: E402  (the answer key's builder: registry, ast helpers)

ROOT = student.ROOT
MAX_FILE_BYTES = 2_000_000          # of one module file read from a zip
MAX_OUTPUT_CHARS = 60_000           # of the grader's output kept per submission
TIME_LIMIT = "time limit"


# ---------------------------------------------------------------------------------------------- the grading tree
def build_grading_tree(dest, root=ROOT) -> pathlib.Path:
    """The student edition of ``root`` in ``dest`` plus the answer key's hidden tests and fixtures, grade.py and the
    registry: what every submission is graded in."""
    root, dest = pathlib.Path(root), pathlib.Path(dest)
    student.build(dest, root=root, quiet=True)
    hidden = list((root / "tests" / "exercises").glob("test_*_hidden.py"))
    hidden += list((root / "tests" / "exercises" / "fixtures").glob("*_hidden.npz"))
    for path in hidden + [root / "tools" / "grade.py", root / "tools" / "exercises.toml"]:
        rel = path.relative_to(root)
        (dest / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(path, dest / rel)
    copy_numba_cache(root, dest)
    return dest


def copy_numba_cache(src_root, tree) -> int:
    """Copy numba's on-disk cache (``__pycache__/*.nbi``, ``*.nbc``) of every module of ``src_root`` whose file in
    ``tree`` is the same (bytes and time stamp: numba checks the time stamp and size of the source), so each
    submission's copy starts with the compiled kernels instead of compiling them again (about 40 s of CPU per
    submission); returns how many files were copied. The cache of a changed module is not copied (numba would
    reject it anyway)."""
    src_root, tree = pathlib.Path(src_root), pathlib.Path(tree)
    count = 0
    for cache in src_root.glob("helpers/**/__pycache__/*.nb[ic]"):
        source = cache.parent.parent / (cache.name.split(".", 1)[0] + ".py")
        rel = source.relative_to(src_root)
        mine = tree / rel
        try:
            same = (source.exists() and mine.exists() and source.stat().st_mtime == mine.stat().st_mtime
                    and source.read_bytes() == mine.read_bytes())
        except OSError:
            same = False
        if same:
            (mine.parent / "__pycache__").mkdir(exist_ok=True)
            shutil.copy2(cache, mine.parent / "__pycache__" / cache.name)
            count += 1
    return count


def exercise_files(reg: dict, root=ROOT) -> dict:
    """{exercise name: [(repo-relative posix path of the module, qualname), ...]} for every target."""
    out = {}
    for ex in reg["exercise"]:
        for target in ex["targets"]:
            module, qualname = student.split_target(target)
            rel = student.module_path(root, module).relative_to(root).as_posix()
            out.setdefault(ex["name"], []).append((rel, qualname))
    return out


def points_of(ex: dict) -> float:
    return float(ex.get("points", 1))


# ---------------------------------------------------------------------------------------------- the zip
def safe_name(name: str) -> str | None:
    """The zip member's path normalised to posix, or None when it is absolute or climbs out (``..``)."""
    name = name.replace("\\", "/")
    if name.startswith("/") or re.match(r"^[A-Za-z]:", name):
        return None
    parts = [p for p in name.split("/") if p not in ("", ".")]
    if not parts or ".." in parts:
        return None
    return "/".join(parts)


def read_modules(zip_path: pathlib.Path, wanted) -> tuple[dict, dict]:
    """Read the module files ``wanted`` (repo-relative paths) from the zip as text, nothing else.
    Returns ({path: source}, {path: reason it is unusable}); raises ValueError when the file is not a zip."""
    sources, problems = {}, {}
    try:
        archive = zipfile.ZipFile(zip_path)
    except (zipfile.BadZipFile, OSError) as err:
        raise ValueError("%s is not a readable zip file (%s)" % (zip_path.name, err)) from None
    with archive:
        members = {}
        for info in archive.infolist():
            name = safe_name(info.filename)
            if name is not None and not info.is_dir():
                members.setdefault(name, info)
        for rel in wanted:
            info = members.get(rel)
            if info is None:
                problems[rel] = "the submission has no file %s" % rel
                continue
            if info.file_size > MAX_FILE_BYTES:
                problems[rel] = "%s is larger than %d bytes" % (rel, MAX_FILE_BYTES)
                continue
            try:
                with archive.open(info) as fh:
                    data = fh.read(MAX_FILE_BYTES + 1)
                text = data.decode("utf-8")
                ast.parse(text, filename=rel)
            except SyntaxError as err:
                problems[rel] = "%s does not parse as Python: %s (line %s)" % (rel, err.msg, err.lineno)
                continue
            except (UnicodeDecodeError, zipfile.BadZipFile, OSError, RuntimeError, ValueError) as err:
                problems[rel] = "%s cannot be read: %s" % (rel, err)
                continue
            sources[rel] = text
    return sources, problems


def answer_cells(root=ROOT) -> list:
    """The answer key's answer cells (tag ``answer``): [{"notebook", "cell", "question"}], in notebook order."""
    out = []
    for path in sorted((pathlib.Path(root) / "notebooks").glob("*.ipynb")):
        for cell in json.loads(path.read_text(encoding="utf-8")).get("cells", []):
            meta = cell.get("metadata", {})
            if "answer" in meta.get("tags", []):
                out.append({"notebook": "notebooks/" + path.name, "cell": cell.get("id"),
                            "question": " ".join(str(meta.get("question", "")).split())})
    return out


def read_answers(zip_path: pathlib.Path, wanted: list) -> list:
    """The student's written answers: for each answer cell of the answer key (``wanted`` = answer_cells()), the
    cell with the same id in the submitted notebook (tag ``student-answer``), as text. Only ``notebooks/*.ipynb``
    members are read, as JSON; the question is the answer key's. Status: answered, unanswered (the prompt as the
    edition left it, or empty), or missing (no such notebook or cell, or a notebook that is not JSON)."""
    import student_docs

    untouched = {"", student_docs.ANSWER_PROMPT.strip(), "# your answer (code)"}
    notebooks = {}
    try:
        with zipfile.ZipFile(zip_path) as archive:
            for info in archive.infolist():
                name = safe_name(info.filename)
                if name and re.fullmatch(r"notebooks/[^/]+\.ipynb", name) and info.file_size <= 20 * MAX_FILE_BYTES:
                    try:
                        with archive.open(info) as fh:
                            nb = json.loads(fh.read(20 * MAX_FILE_BYTES + 1).decode("utf-8"))
                        notebooks.setdefault(name, {c.get("id"): c for c in nb.get("cells", [])
                                                    if isinstance(c, dict)})
                    except (ValueError, AttributeError, zipfile.BadZipFile, OSError, RuntimeError):
                        notebooks.setdefault(name, None)
    except (zipfile.BadZipFile, OSError):
        pass
    out = []
    for want in wanted:
        cells = notebooks.get(want["notebook"])
        cell = cells.get(want["cell"]) if cells else None
        entry = dict(want, answer="", status="missing")
        if cell is not None:
            source = cell.get("source", "")
            text = ("".join(source) if isinstance(source, list) else str(source))[:MAX_OUTPUT_CHARS].strip()
            entry.update(answer=text, status="unanswered" if text in untouched else "answered")
        out.append(entry)
    return out


# ---------------------------------------------------------------------------------------------- merging
def _top_level_names(tree: ast.Module) -> set:
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            for target in (node.targets if isinstance(node, ast.Assign) else [node.target]):
                names.update(n.id for n in ast.walk(target) if isinstance(n, ast.Name))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
    return names


def added_helpers(student_source: str, key_source: str) -> list[str]:
    """Source of the module-level functions of the student's file whose names the answer key's module does not
    define (helpers the student added next to their exercise), decorators included."""
    tree = ast.parse(student_source)
    known = _top_level_names(ast.parse(key_source))
    lines = student_source.splitlines(keepends=True)
    out = []
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name not in known:
            first = min([node.lineno] + [d.lineno for d in node.decorator_list])
            out.append("".join(lines[first - 1:node.end_lineno]))
    return out


def merge_submission(tree: pathlib.Path, sources: dict, files: dict, root=ROOT) -> dict:
    """Write the student's bodies of every target (and their added helpers) into ``tree``.
    ``files`` = exercise_files(); returns {exercise: reason} for exercises that cannot be graded (their stubs stay)."""
    problems = {}
    scratch = pathlib.Path(tempfile.mkdtemp(prefix="student-src-"))
    try:
        for name, targets in files.items():
            for rel, qualname in targets:
                if rel not in sources:
                    continue
                src_file = scratch / rel.replace("/", "__")
                src_file.write_text(sources[rel], encoding="utf-8")
                dest = tree / rel
                before = dest.read_text(encoding="utf-8")
                try:
                    body = student.function_body_source(src_file, qualname)
                    if not body.strip():
                        raise student.BuildError("the body of %s is empty" % qualname)
                    student.replace_body(dest, qualname, body)
                    ast.parse(dest.read_text(encoding="utf-8"))
                except (student.BuildError, SyntaxError, ValueError) as err:
                    dest.write_text(before, encoding="utf-8")
                    problems[name] = "%s: cannot take %s from it: %s" % (
                        rel, qualname, str(err).replace(str(src_file), rel))
        for rel in sorted({r for targets in files.values() for r, _ in targets} & set(sources)):
            extra = added_helpers(sources[rel], (pathlib.Path(root) / rel).read_text(encoding="utf-8"))
            if extra:
                dest = tree / rel
                before = dest.read_text(encoding="utf-8")
                text = before.rstrip("\n") + "\n\n\n# helpers added by the student\n" + "\n\n".join(
                    e.rstrip("\n") + "\n" for e in extra)
                try:
                    ast.parse(text)
                    dest.write_text(text, encoding="utf-8")
                except SyntaxError:
                    pass
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return problems


# ---------------------------------------------------------------------------------------------- running
def run_grader(tree: pathlib.Path, names, timeout: float) -> tuple[str, list | None, bool]:
    """Run the tree's tools/grade.py on ``names`` in its own process (session); (output capped, passed names from
    --status or None, timed out)."""
    status = tree / ".grade-status.json"
    env = grader_env(tree)
    with tempfile.TemporaryFile() as out:
        proc = subprocess.Popen([sys.executable, "tools/grade.py", *names, "--status", str(status)], cwd=str(tree),
                                env=env, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                start_new_session=(os.name == "posix"))
        timed_out = False
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            timed_out = True
            _kill(proc)
        out.seek(0)
        text = out.read(MAX_OUTPUT_CHARS * 4).decode("utf-8", errors="replace")
    if len(text) > MAX_OUTPUT_CHARS:
        text = text[:MAX_OUTPUT_CHARS] + "\n... (output cut at %d characters)\n" % MAX_OUTPUT_CHARS
    passed = None
    if not timed_out and status.exists():
        try:
            passed = list(json.loads(status.read_text(encoding="utf-8")).get("passed", []))
        except (ValueError, AttributeError):
            passed = None
    return text, passed, timed_out


KEPT_ENV = {"PATH", "HOME", "USERPROFILE", "LANG", "TMP", "TEMP", "TMPDIR", "SYSTEMROOT", "SYSTEMDRIVE", "COMSPEC",
            "VIRTUAL_ENV", "CI"}
KEPT_ENV_PREFIXES = ("LC_", "NUMBA_", "OMP_", "MKL_", "OPENBLAS_")


def grader_env(tree: pathlib.Path) -> dict:
    """The grading process's environment: only what Python, numpy and numba need (no tokens or other settings of
    the instructor's shell reach the student's code), one BLAS thread per worker unless set, PYTHONPATH at the
    tree."""
    env = {k: v for k, v in os.environ.items() if k in KEPT_ENV or k.startswith(KEPT_ENV_PREFIXES)}
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env.setdefault(var, "1")
    env.update(PYTHONPATH=str(tree), PYTHONIOENCODING="utf-8", MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1")
    return env


def _kill(proc) -> None:
    try:
        if os.name == "posix":
            os.killpg(proc.pid, signal.SIGKILL)
        else:
            proc.kill()
    except (ProcessLookupError, PermissionError):
        pass
    proc.wait()


def parse_blocks(text: str, names) -> dict:
    """{exercise: (verdict line, block text)} for the per-exercise blocks tools/grade.py printed."""
    head = re.compile(r"^(%s)\s+(passed|FAILED|not written yet)" % "|".join(map(re.escape, names)))
    blocks, current = {}, None
    for line in text.splitlines():
        m = head.match(line)
        if m:
            current = m.group(1)
            blocks[current] = [line]
        elif line.startswith("exercises: "):
            current = None
        elif current is not None and line.startswith(" "):
            blocks[current].append(line)
        else:
            current = None
    return {k: (v[0].split(None, 1)[1].strip(), "\n".join(v)) for k, v in blocks.items()}


# ---------------------------------------------------------------------------------------------- one submission
def grade_submission(zip_path, grading_tree, reg: dict, timeout: float = 300, only=None, root=ROOT,
                     timeout_per_exercise: float = 60, with_answers: bool = True) -> dict:
    """Grade one submission; {"student", "scores": {ex: points}, "total", "reasons": {ex: why 0}, "answers": the
    written answers (read_answers), "feedback": text}.
    Never raises for a bad zip. ``timeout``: the first run (all exercises); ``timeout_per_exercise``: the re-runs
    of single exercises after that run hung or died."""
    zip_path = pathlib.Path(zip_path)
    exercises = [ex for ex in reg["exercise"] if not only or ex["name"] in only]
    names = [ex["name"] for ex in exercises]
    files = {n: t for n, t in exercise_files(reg, root).items() if n in names}
    reasons, lines = {}, []
    scores = {n: 0.0 for n in names}
    try:
        sources, file_problems = read_modules(zip_path, sorted({r for t in files.values() for r, _ in t}))
    except ValueError as err:
        sources, file_problems = None, {}
        reasons = {n: str(err) for n in names}
    output, elapsed = "", 0.0
    if sources is not None:
        for name, targets in files.items():
            bad = [file_problems[r] for r, _ in targets if r in file_problems]
            if bad:
                reasons[name] = "; ".join(dict.fromkeys(bad))
        work = pathlib.Path(tempfile.mkdtemp(prefix="grade-%s-" % re.sub(r"\W", "_", zip_path.stem)[:40]))
        try:
            tree = work / "tree"
            shutil.copytree(grading_tree, tree, ignore=shutil.ignore_patterns("*.pyc", ".pytest_cache"))
            graded_sources = {r: s for r, s in sources.items()}
            for name, reason in merge_submission(tree, graded_sources, files, root).items():
                reasons.setdefault(name, reason)
            # one run for all exercises; when it hangs or dies with several exercises unreported, each of those
            # runs again alone (timeout_per_exercise): a hang costs only its own exercise
            to_run = [n for n in names if n not in reasons]
            queue = [(to_run, timeout)] if to_run else []
            outputs, start = [], time.perf_counter()
            while queue:
                group, limit = queue.pop(0)
                text, passed, timed_out = run_grader(tree, group, limit)
                outputs.append(text.rstrip("\n"))
                blocks = parse_blocks(text, group)
                summary = re.search(r"^exercises: (\d+) passed, (\d+) failed$", text, re.M)
                again = [n for n in group if n not in blocks] if len(group) > 1 else []
                for name in group:
                    verdict = blocks.get(name, ("", ""))[0]
                    if passed is not None and name in passed and verdict.startswith("passed") and summary:
                        scores[name] = points_of(next(e for e in exercises if e["name"] == name))
                    elif name in again:
                        continue
                    elif timed_out and name not in blocks:
                        reasons[name] = "%s: grading stopped after %.0f s" % (TIME_LIMIT, limit)
                    elif name not in blocks:
                        reasons[name] = "the grader reported nothing for it (it crashed; see its output below)"
                if again:
                    outputs.append("(%s: grading each unreported exercise alone)" % (
                        "time limit" if timed_out else "the grader stopped early"))
                    queue += [([n], timeout_per_exercise) for n in again]
            elapsed = time.perf_counter() - start
            output = "\n".join(outputs)
        finally:
            shutil.rmtree(work, ignore_errors=True)
    answers = read_answers(zip_path, answer_cells(root)) if with_answers else []
    total = sum(scores.values())
    possible = sum(points_of(ex) for ex in exercises)
    lines.append("student: %s" % zip_path.stem)
    lines.append("score: %g of %g" % (total, possible))
    lines.append("")
    for ex in exercises:
        name = ex["name"]
        lines.append("%-36s %g / %g%s" % (name, scores[name], points_of(ex),
                                          ("    " + reasons[name]) if name in reasons else ""))
    if answers:
        lines += ["", "written answers (marked by hand): %d of %d answered, %d missing" % (
            sum(a["status"] == "answered" for a in answers), len(answers),
            sum(a["status"] == "missing" for a in answers))]
    if output:
        lines += ["", "--- the grader's report (%.0f s) ---" % elapsed, output.rstrip("\n")]
    return {"student": zip_path.stem, "scores": scores, "total": total, "reasons": reasons, "answers": answers,
            "feedback": "\n".join(lines) + "\n"}


# ---------------------------------------------------------------------------------------------- the batch
def write_results(out_dir: pathlib.Path, results: list, names: list) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "feedback").mkdir(exist_ok=True)
    with open(out_dir / "grades.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(["student"] + names + ["total"])
        for r in sorted(results, key=lambda r: r["student"]):
            writer.writerow([r["student"]] + ["%g" % r["scores"][n] for n in names] + ["%g" % r["total"]])
    for r in results:
        (out_dir / "feedback" / ("%s.txt" % r["student"])).write_text(r["feedback"], encoding="utf-8")
        if r.get("answers"):
            (out_dir / "answers").mkdir(exist_ok=True)
            (out_dir / "answers" / ("%s.json" % r["student"])).write_text(
                json.dumps(r["answers"], indent=1, ensure_ascii=False) + "\n", encoding="utf-8")


def grade_all(submissions_dir, out_dir, jobs: int = 2, timeout_per_submission: float = 300, only=None,
              root=ROOT, progress=None, timeout_per_exercise: float = 60) -> list:
    """Grade every ``*.zip`` of ``submissions_dir`` (student id = the zip's stem) on ``jobs`` parallel workers;
    writes ``out_dir/grades.csv`` and ``out_dir/feedback/<student>.txt``; returns the per-student results.
    ``progress(done, total, result)`` is called as each submission finishes."""
    submissions = sorted(pathlib.Path(submissions_dir).glob("*.zip"))
    out_dir = pathlib.Path(out_dir)
    reg = student.load_registry(root)
    if only:
        unknown = set(only) - {ex["name"] for ex in reg["exercise"]}
        if unknown:
            raise ValueError("unknown exercise(s): %s" % ", ".join(sorted(unknown)))
    names = [ex["name"] for ex in reg["exercise"] if not only or ex["name"] in only]
    work = pathlib.Path(tempfile.mkdtemp(prefix="grade-all-"))
    results = []
    try:
        tree = build_grading_tree(work / "grading-tree", root)

        def one(path):
            try:
                return grade_submission(path, tree, reg, timeout_per_submission, only, root, timeout_per_exercise)
            except Exception as err:    # noqa: BLE001  (one submission never stops the batch)
                return {"student": path.stem, "scores": {n: 0.0 for n in names}, "total": 0.0,
                        "reasons": {n: "grading error" for n in names},
                        "feedback": "student: %s\nscore: 0\n\nthe grader could not grade this submission: %s: %s\n"
                                    % (path.stem, type(err).__name__, err)}

        with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
            futures = [pool.submit(one, p) for p in submissions]
            for future in concurrent.futures.as_completed(futures):
                results.append(future.result())
                if progress:
                    progress(len(results), len(submissions), results[-1])
    finally:
        shutil.rmtree(work, ignore_errors=True)
    write_results(out_dir, results, names)
    return results


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="Grade every submission zip of a folder (see the module docstring).")
    parser.add_argument("submissions", type=pathlib.Path)
    parser.add_argument("--out", type=pathlib.Path, default=None, help="default: SUBMISSIONS/graded")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--timeout", type=float, default=300, help="seconds per submission (one run of all)")
    parser.add_argument("--timeout-exercise", type=float, default=60,
                        help="seconds per exercise when it is re-run alone after a hang or crash")
    parser.add_argument("--only", nargs="+", default=None, help="grade only these exercises")
    args = parser.parse_args(argv)
    if not args.submissions.is_dir():
        print("no folder %s" % args.submissions, file=sys.stderr)
        return 2
    out = args.out or args.submissions / "graded"
    start = time.perf_counter()

    def progress(done, total, result):
        width = 30
        bar = "#" * (width * done // max(total, 1))
        print("[%-*s] %d/%d  %-24s %g" % (width, bar, done, total, result["student"], result["total"]), flush=True)

    try:
        results = grade_all(args.submissions, out, args.jobs, args.timeout, args.only, progress=progress,
                            timeout_per_exercise=args.timeout_exercise)
    except (ValueError, student.BuildError) as err:
        print("error: %s" % err, file=sys.stderr)
        return 2
    print("graded %d submissions in %.0f s: %s, %s" % (len(results), time.perf_counter() - start,
                                                       out / "grades.csv", out / "feedback"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
