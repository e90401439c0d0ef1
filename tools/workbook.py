"""The workbook's tasks on every platform: the Makefile delegates here, and Windows runs this script directly.

    python3 tools/workbook.py figures      # = make figures   (Windows: py -3.11 tools\\workbook.py figures)
    python3 tools/workbook.py test         # = make test
    python3 tools/workbook.py lab          # = make lab
    python3 tools/workbook.py setup | test-unit | test-notebooks | notebooks | execute NB... | bench
    python3 tools/workbook.py clean | distclean
    python3 tools/workbook.py student [DEST]       # = make student: the student edition in build/student
    python3 tools/workbook.py grade [NAME]         # = make grade [EX=NAME]: grade the exercises
    python3 tools/workbook.py submission           # = make submission: the student's work in submission.zip
    python3 tools/workbook.py grade-all SUBMISSIONS_DIR  # grade a folder of submission zips (tools/grade_all.py)
    python3 tools/workbook.py gradescope           # the Gradescope autograder zip (tools/gradescope.py)
    python3 tools/workbook.py release TREE NAME... # model solutions / answers into a student tree (tools/release.py)
    python3 tools/workbook.py answers SUBMISSIONS_DIR  # written answers per question, as HTML for marking

The interpreter that runs this script is checked first (CPython 3.11.5 to 3.13) and is the one the virtual
environment ``.venv`` is made from. ``.venv`` is (re)created when it is missing, when it was made by another
interpreter, or when its last install did not finish; it is reinstalled in place when ``environment.txt``,
``environment-peers.txt`` or ``pyproject.toml`` changed. The optional peers (GTSAM, g2o) are installed from
wheels where wheels exist; the workbook does not need them.

With ``CI=true`` the ``test`` task runs the unit tests and the strict notebook pass twice more on a lowered CPU:
numpy's dispatch without AVX-512, then without AVX-512 and AVX2 (numba then compiling for a generic x86-64), one
BLAS thread each, to prove that neither the stored outputs nor the tests depend on the processor (the unit tests
marked ``cpu_independent``, whose results these settings cannot reach, are left out of those passes).
In the student edition (a tree with EXERCISES.md, written by ``make student``) ``test`` runs the grader, which
fails only when a test outside the exercises fails, then nbval in lax mode over the notebooks whose exercises
all pass; in the answer key, with ``CI=true``, ``test`` ends with the student-edition check
(``tools/student_check.py``) and the browser check of an exploration notebook (``tools/browser_check.py``: Debian's
Chromium and Playwright are installed for it under ``CI=true`` only).
The unit tests and the notebook passes run on one pytest-xdist worker per core (at most 4; ``WORKBOOK_JOBS=N``
sets the number, 1 runs them in one process).
This file keeps to syntax that old Pythons can parse, so that they reach the version check.
"""
import hashlib
import json
import os
import pathlib
import platform
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ElementTree

ROOT = pathlib.Path(__file__).resolve().parents[1]
VENV = ROOT / ".venv"
STATE = VENV / "workbook-install.json"
LOCK_FILES = ("environment.txt", "environment-peers.txt", "pyproject.toml")
SUPPORTED = ((3, 11, 5), (3, 14, 0))  # lower bound inclusive, upper bound exclusive
SUPPORTED_TEXT = "CPython 3.11.5 to 3.13"
NB_TIMEOUT = int(os.environ.get("NB_TIMEOUT", "600"))
# The CI passes on a lowered CPU (x86-64 only): numpy's dispatch groups switched off (numpy 2.4's names), and in the
# lowest pass numba compiling for a generic x86-64 (no AVX, no FMA); each pass also gets one BLAS thread.
CPU_PASSES = (("AVX-512 off", {"NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"}),
              ("AVX-512 and AVX2 off, numba generic",
               {"NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR", "NUMBA_CPU_NAME": "generic"}))
#: the unit tests left out of the lowered-CPU passes: marked so because no setting of those passes reaches their
#: results (text processing of the source tree, the compiled peer libraries GTSAM and g2o)
CPU_INDEPENDENT = "cpu_independent"


class TaskError(Exception):
    """A task failed; the message is the one line printed."""


def check_interpreter():
    version = sys.version_info[:3]
    name = platform.python_implementation()
    if name != "CPython" or not SUPPORTED[0] <= version < SUPPORTED[1]:
        found = "%s %s (%s)" % (name, platform.python_version(), sys.executable)
        raise TaskError("this workbook needs %s; found %s. Run with a supported Python, e.g. `make test "
                        "PYTHON=python3.12` or `py -3.12 tools\\workbook.py test`." % (SUPPORTED_TEXT, found))


def venv_python():
    if os.name == "nt":
        return VENV / "Scripts" / "python.exe"
    return VENV / "bin" / "python"


def interpreter_identity():
    return {"executable": os.path.realpath(sys.executable), "version": platform.python_version()}


def lock_digest():
    h = hashlib.sha256()
    for name in LOCK_FILES:
        h.update(name.encode())
        h.update((ROOT / name).read_bytes())
    return h.hexdigest()


def read_state():
    try:
        return json.loads(STATE.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def run(cmd, env=None, check=True):
    """Run a command from the repository root; a failure raises TaskError naming it."""
    print("+ " + " ".join(str(c) for c in cmd), flush=True)
    code = subprocess.call([str(c) for c in cmd], cwd=str(ROOT), env=env)
    if check and code != 0:
        raise TaskError("command failed with exit status %d: %s" % (code, " ".join(str(c) for c in cmd)))
    return code


def pip_args():
    # Progress bars in a terminal; quiet, bar-free logs otherwise (CI, IDE runners).
    return [] if sys.stdout.isatty() else ["--quiet", "--progress-bar", "off"]


def setup():
    """Create or refresh .venv so that it holds exactly the lock; never leave a half-installed one behind."""
    check_interpreter()
    state = read_state()
    identity = interpreter_identity()
    if VENV.exists() and (state is None or state.get("interpreter") != identity):
        why = "its last install did not finish" if state is None else "it was made by another interpreter"
        print("recreating .venv: %s" % why, flush=True)
        shutil.rmtree(VENV)
    digest = lock_digest()
    if state is not None and state.get("interpreter") == identity and state.get("lock") == digest \
            and venv_python().exists():
        return
    if not VENV.exists():
        run([sys.executable, "-m", "venv", VENV])
    if STATE.exists():
        STATE.unlink()  # from here until the install succeeds, .venv counts as unfinished
    py = venv_python()
    run([py, "-m", "pip", "install"] + pip_args() + ["-r", "environment.txt"])
    peers = install_peers(py)
    STATE.write_text(json.dumps({"interpreter": identity, "lock": digest, "peers": peers}, indent=1),
                     encoding="utf-8")
    print("environment ready: %s (Python %s)%s" % (VENV.name, identity["version"],
                                                  "" if peers else "; optional peers not installed"), flush=True)


def install_peers(py):
    """Install the optional peers from wheels; a platform without wheels is reported, not an error."""
    code = run([py, "-m", "pip", "install", "--only-binary=:all:", "--no-deps"] + pip_args()
               + ["-r", "environment-peers.txt"], check=False)
    if code != 0:
        print("note: the optional peers (environment-peers.txt) have no wheels here; the workbook runs without "
              "them and shows their recorded results", flush=True)
    return code == 0


def tool_env(extra=None):
    env = dict(os.environ)
    env["JUPYTER_PLATFORM_DIRS"] = "1"  # Jupyter's new path layout (silences its migration warning)
    env["PYDEVD_DISABLE_FILE_VALIDATION"] = "1"
    env.update(extra or {})
    return env


def parallel_args():
    """pytest-xdist workers: one per core, at most 4 (``WORKBOOK_JOBS=N`` overrides; 1 runs in one process)."""
    jobs = os.environ.get("WORKBOOK_JOBS", "").strip()
    if jobs and not jobs.isdigit():
        raise TaskError("WORKBOOK_JOBS must be a whole number of test workers (1 = no parallel run), got %r" % jobs)
    n = int(jobs) if jobs else min(os.cpu_count() or 1, 4)
    return ["-n", str(n)] if n > 1 else []


def stored_run_seconds(path):
    """Seconds the notebook's cells took when its outputs were stored (nbclient's per-cell timing), 0 if unknown."""
    import datetime
    total = 0.0
    try:
        cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    except (OSError, ValueError, KeyError):
        return total
    for cell in cells:
        timing = cell.get("metadata", {}).get("execution", {})
        try:
            start, end = (datetime.datetime.fromisoformat(timing[k].replace("Z", "+00:00"))
                          for k in ("iopub.execute_input", "shell.execute_reply"))
        except (KeyError, ValueError, AttributeError):
            continue
        total += max((end - start).total_seconds(), 0.0)
    return total


#: How jupyter_client reports a kernel that did not start. Two workers starting kernels at the same moment can
#: race for a TCP port (zmq "Address already in use"); the notebook then never ran, so it is run again.
KERNEL_START_FAILURES = ("Kernel died before replying to kernel_info", "Kernel didn't respond in")


def kernel_start_failures(report, notebooks):
    """The notebooks of a junit-xml ``report`` that failed, when every failure in it is a kernel that did not
    start; None when any other failure is there (or the report cannot be read)."""
    try:
        cases = list(ElementTree.parse(str(report)).iter("testcase"))
    except (OSError, ElementTree.ParseError):
        return None
    by_class = {p.relative_to(ROOT).with_suffix("").as_posix().replace("/", ".") + ".ipynb": p for p in notebooks}
    failed = set()
    for case in cases:
        for bad in case.findall("failure") + case.findall("error"):
            text = (bad.get("message") or "") + (bad.text or "")
            if case.get("classname") not in by_class or not any(s in text for s in KERNEL_START_FAILURES):
                return None
            failed.add(by_class[case.get("classname")])
    return sorted(failed) or None


def nbval(env=None):
    """Strict nbval over every notebook; with several workers each notebook runs whole in one kernel
    (``--dist loadscope``), longest first so that the workers finish together. Notebooks that failed only
    because their kernel did not start (``KERNEL_START_FAILURES``) run again once, on one worker."""
    workers = parallel_args()
    notebooks = sorted((ROOT / "notebooks").glob("*.ipynb"))
    if workers:
        notebooks.sort(key=stored_run_seconds, reverse=True)
        workers += ["--dist", "loadscope", "--no-loadscope-reorder"]
    report = ROOT / "build" / "nbval-report.xml"
    report.parent.mkdir(exist_ok=True)
    strict = [venv_python(), "-m", "pytest", "-W", "error", "-q", "--nbval", "--nbval-current-env",
              "--nbval-sanitize-with", "notebooks/nbval_sanitize.cfg", "--nbval-cell-timeout", "300",
              "-p", "no:cacheprovider"]
    cmd = strict + ["--junitxml", str(report)] + workers + [str(p.relative_to(ROOT)) for p in notebooks]
    code = run(cmd, env=tool_env(worker_env(workers, env)), check=False)
    if code == 0:
        return
    again = kernel_start_failures(report, notebooks) if workers else None
    if not again:
        raise TaskError("command failed with exit status %d: %s" % (code, " ".join(str(c) for c in cmd)))
    print("%d notebook(s) failed only because their kernel did not start: running them again on one worker"
          % len(again), flush=True)
    run(strict + [str(p.relative_to(ROOT)) for p in again], env=tool_env(worker_env([], env)))


def worker_env(workers, env=None):
    """With several workers, one BLAS thread each (unless set): the workers already use every core."""
    env = dict(env or {})
    if workers:
        for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
            if name not in os.environ:
                env.setdefault(name, "1")
    return env


def cpu_passes():
    """The lowered-CPU environments (label, variables) for this machine (x86-64 only)."""
    machine = platform.machine().lower()
    if machine not in ("x86_64", "amd64"):
        print("lowered-CPU passes: only defined for x86-64, skipped on %s" % machine, flush=True)
        return []
    return [(label, dict(variables, OPENBLAS_NUM_THREADS="1")) for label, variables in CPU_PASSES]


def describe(label, env):
    return "%s and one BLAS thread (%s)" % (label, ", ".join("%s=%r" % (k, env[k]) for k in sorted(env)
                                                                  if k != "OPENBLAS_NUM_THREADS"))


STUDENT_EDITION = (ROOT / "EXERCISES.md").exists()
GRADE_STATUS = ROOT / "build" / "grade-status.json"


def in_ci():
    return os.environ.get("CI", "").lower() in ("1", "true", "yes")


def test_unit():
    setup()
    if STUDENT_EDITION:  # unfinished exercises are expected: only the other tests can fail this
        run([venv_python(), "tools/grade.py", "--student-ok", "--status", GRADE_STATUS], env=tool_env())
        return
    lint()
    unit_tests()
    if in_ci():
        for label, env in cpu_passes():
            print("unit tests again with %s, without the %s tests" % (describe(label, env), CPU_INDEPENDENT),
                  flush=True)
            unit_tests(env, ["-m", "not " + CPU_INDEPENDENT])


def lint():
    """ruff over the Python sources, with the rules of pyproject.toml ([tool.ruff])."""
    run([venv_python(), "-m", "ruff", "check", "helpers", "tests", "tools", "benchmarks"], env=tool_env())


def unit_tests(env=None, select=()):
    workers = parallel_args()
    run([venv_python(), "-m", "pytest", "-W", "error", "-q"] + list(select) + workers + ["tests"],
        env=tool_env(worker_env(workers, env)))


def test_notebooks():
    setup()
    if STUDENT_EDITION:
        student_notebooks()
        return
    nbval()
    if in_ci():
        for label, env in cpu_passes():
            print("strict nbval again with %s" % describe(label, env), flush=True)
            nbval(env)


def test():
    test_unit()
    test_notebooks()
    if in_ci() and not STUDENT_EDITION:
        run([venv_python(), "tools/student_check.py"], env=tool_env())
        run([venv_python(), "tools/browser_check.py", BROWSER_CHECK_NOTEBOOK, "--artifacts", "build/browser-check"],
            env=tool_env())


#: the exploration notebook that ``CI=true make test`` opens in headless Chromium (tools/browser_check.py)
BROWSER_CHECK_NOTEBOOK = "notebooks/05_snn_demo.ipynb"


def student_notebooks():
    """nbval --nbval-lax over the student notebooks whose exercises all passed the last grading."""
    import tomllib
    if not GRADE_STATUS.exists():
        run([venv_python(), "tools/grade.py", "--student-ok", "--status", GRADE_STATUS], env=tool_env())
    passed = set(json.loads(GRADE_STATUS.read_text(encoding="utf-8"))["passed"])
    with open(str(ROOT / "tools" / "exercises.toml"), "rb") as fh:
        exercises = tomllib.load(fh)["exercise"]
    blocked = {nb for ex in exercises if ex["name"] not in passed for nb in ex.get("notebooks", [])}
    ready = [p for p in sorted((ROOT / "notebooks").glob("*.ipynb")) if p.stem not in blocked]
    print("notebooks whose exercises all pass: %d of %d" % (len(ready), len(ready) + len(blocked)), flush=True)
    if ready:
        run([venv_python(), "-m", "pytest", "-W", "error", "-q", "--nbval-lax", "--nbval-current-env",
             "--nbval-cell-timeout", "300", "-p", "no:cacheprovider"] + [p.relative_to(ROOT) for p in ready],
            env=tool_env())


def instructor_tool(script, args):
    """Run an instructor's tool of the answer key (tools/grade_all.py, gradescope.py, release.py)."""
    if not (ROOT / script).exists():
        raise TaskError("%s is the instructor's tool: it is in the answer key, not in the student edition" % script)
    setup()
    run([venv_python(), script] + list(args), env=tool_env())


def student(args=()):
    """The student edition: build/student, or the folder given (``student DEST``); ``--help``: tools/student.py's."""
    args = list(args)
    if {"-h", "--help"} & set(args) or len(args) > 1:
        raise TaskError("usage: workbook.py student [DEST]  (default build/student; tools/student.py --help for more)")
    run([sys.executable, "tools/student.py", "build"] + args)


def grade(args):
    setup()
    code = run([venv_python(), "tools/grade.py"] + [a for a in args if a], env=tool_env(), check=False)
    if code != 0:
        raise TaskError("not every exercise graded passed (the lines above say which)")


def figures():
    setup()
    run([venv_python(), "tools/execute_notebooks.py", "--output-dir", "build/notebooks",
         "--timeout", str(NB_TIMEOUT)], env=tool_env())
    n = len(list((ROOT / "figures").glob("*.png")))
    print("report figures in figures/: %d PNG, %d PDF" % (n, len(list((ROOT / "figures").glob("*.pdf")))))


def execute(notebooks):
    setup()
    run([venv_python(), "tools/execute_notebooks.py", "--inplace", "--timeout", str(NB_TIMEOUT)]
        + list(notebooks), env=tool_env())


def lab():
    setup()
    run([venv_python(), "-m", "jupyterlab", "--notebook-dir=notebooks"], env=tool_env())


def bench():
    setup()
    for script in sorted((ROOT / "benchmarks").glob("*.py")):
        run([venv_python(), script.relative_to(ROOT)], env=tool_env())


def clean(everything=False):
    """Remove build/, figures/ and caches (and .venv with ``everything``). The student edition in build/student
    loses only the files its build wrote (tools/student.py clean): an instructor's .git or notes there stay."""
    edition = ROOT / "build" / "student"
    if (edition / ".student-edition-files").exists() and (ROOT / "tools" / "student.py").exists():
        run([sys.executable, "tools/student.py", "clean", str(edition)])
    for name in ["build", "figures", ".pytest_cache"] + ([".venv"] if everything else []):
        path = ROOT / name
        if name == "build" and edition.exists():          # keep what is left of build/student
            for child in path.iterdir():
                if child != edition:
                    shutil.rmtree(str(child), ignore_errors=True) if child.is_dir() else child.unlink()
            print("removed build/ (build/student: only what its build wrote)")
            continue
        shutil.rmtree(str(path), ignore_errors=True)
        print("removed %s/" % name)


TASKS = {
    "setup": lambda args: setup(),
    "figures": lambda args: figures(),
    "test": lambda args: test(),
    "test-unit": lambda args: test_unit(),
    "test-notebooks": lambda args: test_notebooks(),
    "notebooks": lambda args: execute([]),
    "execute": lambda args: execute(args),
    "lab": lambda args: lab(),
    "bench": lambda args: bench(),
    "student": lambda args: student(args),
    "submission": lambda args: run([sys.executable, "tools/submission.py"] + list(args)),
    "grade-all": lambda args: instructor_tool("tools/grade_all.py", args),
    "gradescope": lambda args: instructor_tool("tools/gradescope.py", ["build"] + list(args)),
    "release": lambda args: instructor_tool("tools/release.py", ["solutions"] + list(args)),
    "answers": lambda args: instructor_tool("tools/release.py", ["answers"] + list(args)),
    "grade": lambda args: grade(args),
    "student-check": lambda args: (setup(), run([venv_python(), "tools/student_check.py"], env=tool_env())),
    "clean": lambda args: clean(),
    "distclean": lambda args: clean(everything=True),
    "check-python": lambda args: (check_interpreter(), print("%s %s: supported" % (
        platform.python_implementation(), platform.python_version()))),
}


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] not in TASKS:
        print(__doc__)
        print("tasks: " + ", ".join(TASKS))
        return 2
    try:
        TASKS[argv[0]](argv[1:])
    except TaskError as err:
        print("error: %s" % err, file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
