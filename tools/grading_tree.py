"""The grading tree a class is graded in, running the answer key's grader in it, and scoring by test group.

The grading tree is the student edition built from the answer key (tools/student.py) plus the answer key's hidden
tests and hidden fixtures, its ``tools/grade.py`` and ``tools/exercises.toml``; each submission is graded in its own
copy of it (tools/grade_all.py, tools/gradescope.py). ``run_grader`` runs that copy's ``tools/grade.py`` in its own
process (its own session: killed whole at the time limit) with a minimal environment and its output capped.

Scores: every test function of an exercise belongs to one group of the registry (``[exercise.groups.ID]`` with
``title``, ``points``, ``tests``); a group scores its points when every test in it passed (a test that did not run,
e.g. after a time limit or a file that does not import, counts as failed); the exercise's score is the sum of its
passed groups. An exercise without groups has one group of all its tests worth its ``points`` (default 1).
"""
from __future__ import annotations

import ast
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

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import student  # noqa: E402  (the answer key's builder)

ROOT = student.ROOT
MAX_OUTPUT_CHARS = 60_000           # of the grader's output kept per run
TEST_TIME_LIMIT = 60.0              # seconds per check in the grading runs


# ---------------------------------------------------------------------------------------------- the grading tree
def build_grading_tree(dest, root=ROOT) -> pathlib.Path:
    """The student edition of ``root`` in ``dest`` plus the answer key's hidden tests and fixtures, grade.py and the
    registry: what every submission is graded in."""
    root, dest = pathlib.Path(root), pathlib.Path(dest)
    student.build(dest, root=root, quiet=True)
    hidden = list((root / "tests" / "exercises").glob("*_hidden.py"))      # hidden tests and their helpers
    hidden += list((root / "tests" / "exercises" / "fixtures").glob("*_hidden.npz"))
    for path in hidden + [root / "tools" / name for name in ("grade.py", "grade_guard.py", "exercises.toml")]:
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


# ---------------------------------------------------------------------------------------------- running
def run_grader(tree: pathlib.Path, names, timeout: float,
               test_limit: float = TEST_TIME_LIMIT) -> tuple[str, dict, str | None]:
    """Run the tree's tools/grade.py on ``names`` (every failed check shown) in its own process and session under
    tools/grade_guard.py (no file changed outside ``tree``'s parent, the submission's work folder).
    Time limits: inside, a check over ``test_limit`` seconds fails (pytest-timeout; Python code only); outside, a
    watchdog reads the progress file and kills the process whole when a check runs past the limit anyway (code
    stuck in C holds the interpreter) or the run passes ``timeout``. Returns (its output, capped; read_progress();
    None, "check" or "run": which limit killed it)."""
    progress = tree / ".grade-progress.jsonl"
    progress.unlink(missing_ok=True)
    with tempfile.TemporaryFile() as out:
        command = [sys.executable, "tools/grade_guard.py", str(tree.parent), "tools/grade.py", *names, "--all",
                   "--timeout", "%g" % test_limit, "--progress", str(progress)]
        proc = subprocess.Popen(command, cwd=str(tree), env=grader_env(tree), stdout=out,
                                stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                start_new_session=(os.name == "posix"))
        killed = _watch(proc, progress, time.time() + timeout, 1.2 * test_limit + 2)
        ended = time.time()
        out.seek(0)
        text = out.read(MAX_OUTPUT_CHARS * 4).decode("utf-8", errors="replace")
    if len(text) > MAX_OUTPUT_CHARS:
        text = text[:MAX_OUTPUT_CHARS] + "\n... (output cut at %d characters)\n" % MAX_OUTPUT_CHARS
    return text, read_progress(progress, ended), killed


def _watch(proc, progress: pathlib.Path, deadline: float, check_limit: float) -> str | None:
    """Wait for ``proc``; kill it when the run passes ``deadline`` ("run") or one check runs longer than
    ``check_limit`` seconds ("check"); None when it ended by itself."""
    while True:
        try:
            proc.wait(timeout=0.5)
            return None
        except subprocess.TimeoutExpired:
            pass
        now = time.time()
        if now > deadline:
            _kill(proc)
            return "run"
        state = read_progress(progress, now)
        if state["running"] and state["running_for"] > check_limit:
            _kill(proc)
            return "check"


def read_progress(path: pathlib.Path, ended: float) -> dict:
    """What a grading run got through, from its ``--progress`` lines (a line cut by a kill is ignored):
    {"collected": [nodeid], "outcomes": {nodeid: outcome}, "failures": {nodeid: {"title", "text"}}, "running": the
    check started and not finished or None, "running_for": its seconds until ``ended``, "finished": bool}."""
    out = {"collected": [], "outcomes": {}, "failures": {}, "running": None, "running_for": 0.0, "finished": False}
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        lines = []
    started = 0.0
    for line in lines:
        try:
            entry = json.loads(line)
        except ValueError:
            continue
        if not isinstance(entry, dict):
            continue
        if "collected" in entry:
            out["collected"] = [str(n) for n in entry["collected"]]
        elif "start" in entry:
            out["running"], started = str(entry["start"]), float(entry.get("time", ended))
        elif "done" in entry:
            nodeid = str(entry["done"])
            out["outcomes"][nodeid] = str(entry.get("outcome", "failed"))
            if out["outcomes"][nodeid] == "failed":
                out["failures"][nodeid] = {"title": str(entry.get("title", "")), "text": str(entry.get("text", ""))}
            out["running"] = None
        elif entry.get("finished"):
            out["finished"] = True
    out["running_for"] = ended - started if out["running"] else 0.0
    return out


def exercise_of(nodeid: str) -> str:
    """``tests/exercises/test_NAME[_hidden].py::...`` → NAME (as tools/grade.py)."""
    stem = pathlib.PurePosixPath(nodeid.split("::")[0]).stem
    return re.sub(r"_hidden$", "", stem[len("test_"):])


KEPT_ENV = {"PATH", "LANG", "SYSTEMROOT", "SYSTEMDRIVE", "COMSPEC", "VIRTUAL_ENV", "CI"}
KEPT_ENV_PREFIXES = ("LC_", "NUMBA_", "OMP_", "MKL_", "OPENBLAS_")


def grader_env(tree: pathlib.Path) -> dict:
    """The grading process's environment: only what Python, numpy and numba need (no tokens or other settings of
    the instructor's shell reach the student's code), one BLAS thread per worker unless set, PYTHONPATH at the
    tree, and the home and temporary folders inside the submission's work folder (``tree/..``), so code that
    writes or deletes under ``~`` or the temporary folder touches only its own copy."""
    env = {k: v for k, v in os.environ.items() if k in KEPT_ENV or k.startswith(KEPT_ENV_PREFIXES)}
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env.setdefault(var, "1")
    home, tmp = pathlib.Path(tree).parent / "home", pathlib.Path(tree).parent / "tmp"
    home.mkdir(exist_ok=True)
    tmp.mkdir(exist_ok=True)
    env.update(PYTHONPATH=str(tree), PYTHONIOENCODING="utf-8", MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1",
               HOME=str(home), USERPROFILE=str(home), TMPDIR=str(tmp), TMP=str(tmp), TEMP=str(tmp),
               MPLCONFIGDIR=str(home / ".matplotlib"))
    return env


def set_read_only(path: pathlib.Path, read_only: bool) -> None:
    """Make every file and folder under ``path`` read-only (or writable again for its owner): the shared grading
    tree is read-only while submissions are graded (POSIX permissions; a no-op for folders on Windows)."""
    for p in [pathlib.Path(path), *pathlib.Path(path).rglob("*")]:
        if p.is_symlink():
            continue
        mode = p.stat().st_mode
        p.chmod(mode & ~0o222 if read_only else mode | 0o200)


def _kill(proc) -> None:
    try:
        if os.name == "posix":
            os.killpg(proc.pid, signal.SIGKILL)
        else:
            proc.kill()
    except (ProcessLookupError, PermissionError):
        pass
    proc.wait()



# ---------------------------------------------------------------------------------------------- scores
def test_functions(name: str, root=ROOT) -> dict:
    """{test function name: True when it is in the hidden file} of exercise ``name``'s test files at ``root``."""
    out = {}
    for hidden, fname in ((False, "test_%s.py" % name), (True, "test_%s_hidden.py" % name)):
        path = pathlib.Path(root) / "tests" / "exercises" / fname
        if path.exists():
            tree = ast.parse(path.read_text(encoding="utf-8"))
            out.update({n.name: hidden for n in tree.body
                        if isinstance(n, ast.FunctionDef) and n.name.startswith("test_")})
    return out


def groups_of(ex: dict, root=ROOT) -> list[dict]:
    """The exercise's test groups: [{"id", "title", "points", "tests", "hidden"}] in registry order."""
    funcs = test_functions(ex["name"], root)
    groups = ex.get("groups") or {"all": {"title": "all checks", "points": ex.get("points", 1), "tests": list(funcs)}}
    return [{"id": gid, "title": g["title"], "points": float(g["points"]), "tests": list(g["tests"]),
             "hidden": any(funcs.get(t, False) for t in g["tests"])} for gid, g in groups.items()]


def points_of(ex: dict) -> float:
    return float(ex.get("points", 1))


def score_groups(ex: dict, outcomes: dict, root=ROOT, reason: str | None = None, failures=None) -> list[dict]:
    """Each group of ``ex`` with its score: ``outcomes`` = {pytest node id: "passed" | "failed" | "skipped"} of the
    grading run; a group scores its points when each of its test functions ran and every run of it (each
    parametrisation) passed. ``reason`` (the exercise could not be graded) scores every group 0.
    Adds "score", "failed" (the test functions that did not pass) and "output" (what failed: each check's title,
    its message from ``failures`` = {node id: {"title", "text"}}, and the registry's hint) to each group."""
    by_func, texts = {}, {}
    for nodeid, outcome in outcomes.items():
        path, _, rest = nodeid.partition("::")
        stem = pathlib.PurePosixPath(path).stem
        if stem in ("test_%s" % ex["name"], "test_%s_hidden" % ex["name"]):
            func = rest.split("[")[0]
            by_func.setdefault(func, []).append(outcome)
            if (failures or {}).get(nodeid):
                texts.setdefault(func, failures[nodeid])
    hints = ex.get("hints", {})
    out = []
    for group in groups_of(ex, root):
        failed = [t for t in group["tests"] if reason or not by_func.get(t)
                  or any(o != "passed" for o in by_func[t])]
        lines = [reason] if reason else []
        for func in [] if reason else failed:
            info = texts.get(func) or {"title": func, "text": "did not run (skipped after an earlier failure)"}
            lines += ["✗ %s (%s)" % (info["title"] or func, func), "    " + info["text"].replace("\n", "\n    ")]
            lines += ["  hint: " + " ".join(hints[func].split())] if func in hints else []
        out.append(dict(group, failed=failed, score=0.0 if failed else group["points"], output="\n".join(lines)))
    return out
