"""Build the student edition of the workbook from the answer key (this repository) and check it.

    python tools/student.py build [DEST]          # = make student (DEST defaults to build/student)
    python tools/student.py check DEST            # the self-check alone, on an existing student tree
    python tools/student.py copy-solution DEST EX # the answer key's body of exercise EX into DEST (the CI check)
    python tools/student.py clean DEST            # remove what the last build wrote into DEST, nothing else

The registry ``tools/exercises.toml`` names every exercise's target functions. The build copies the tracked
tree (``git ls-files``; outside a git checkout a walk that skips .venv, build, figures and caches) to DEST, then
(a rebuild first removes only the files the last build listed in DEST/.student-edition-files; it refuses a
non-empty DEST it did not make, so an instructor's .git or notes there are never deleted)

1. replaces each target's body (found with ``ast``; decorators, signature and docstring kept) by
   ``raise ExerciseNotImplemented("<name>", "EXERCISES.md, section <name>")``;
2. applies the registry's ``rewrite`` entries (fast paths routed to the student's reference), ``redact``
   entries (text blocks that show a solution or describe a removed fast path) and ``notebook_cell`` entries
   (notebook cells about a removed fast path), removes the answer-key-only paths and checks that every ``kept``
   entry (a function close to an exercise that stays, with the reason) still names a function;
3. strips notebook outputs except the kept ones, adds a cell naming each notebook's exercises and the import of
   ``helpers.exercises`` (short messages) to the first code cell;
4. writes EXERCISES.md and the student README, then self-checks: every target's body is the stub (compared as
   ASTs) and no line of a solution body appears in any .py or .ipynb file of DEST.
Standard library only; runs on every platform.
"""
from __future__ import annotations

import ast
import json
import os
import pathlib
import shutil
import subprocess
import sys
import textwrap
import tomllib

ROOT = pathlib.Path(__file__).resolve().parents[1]
REGISTRY = "tools/exercises.toml"
SKIP_DIRS = {".venv", "build", "figures", ".git", "__pycache__", ".pytest_cache", ".hypothesis",
             ".ipynb_checkpoints"}
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from student_docs import lines_of, write_docs  # noqa: E402  (EXERCISES.md, the student README, the notebooks)

IMPORT_LINE = "from helpers.exercises import ExerciseNotImplemented  # student edition: exercise stubs raise it"
# helpers.graph may import only itself and the bottom layer (tests/test_layers.py); helpers.exercises imports
# nothing from helpers, so the graph modules load it by name instead of with an import statement.
IMPORT_LINE_GRAPH = ("ExerciseNotImplemented = __import__('importlib').import_module("
                     "'helpers.exercises').ExerciseNotImplemented  # student edition: exercise stubs raise it")
NOTEBOOK_IMPORT = "import helpers.exercises  # short messages for unimplemented exercises"
MIN_LEAK_CHARS = 16


class BuildError(Exception):
    """The registry does not fit the source, or the self-check failed; the message says where."""


# ---------------------------------------------------------------------------------------------- registry
def load_registry(root=ROOT) -> dict:
    with open(pathlib.Path(root) / REGISTRY, "rb") as fh:
        reg = tomllib.load(fh)
    reg.setdefault("edition", {})
    names = [ex["name"] for ex in reg.get("exercise", [])]
    if len(set(names)) != len(names):
        raise BuildError("duplicate exercise names in %s" % REGISTRY)
    for ex in reg["exercise"]:
        if not ex.get("targets"):
            raise BuildError("exercise %s has no targets" % ex["name"])
        if not (pathlib.Path(root) / "tests" / "exercises" / ("test_%s.py" % ex["name"])).exists():
            raise BuildError("exercise %s has no tests/exercises/test_%s.py" % (ex["name"], ex["name"]))
        ex.setdefault("notebooks", [])
        ex.setdefault("hints", {})
    return reg


def shipped(rel: str, remove) -> bool:
    """Whether the answer key's file ``rel`` goes into the student edition: not a removed path, and of tests/
    only the public exercise tests, their checks and their public fixtures (hidden tests and fixtures, and the
    answer key's own tests, stay with the answer key)."""
    if any(rel == r or rel.startswith(r.rstrip("/") + "/") for r in remove):
        return False
    if rel.startswith("tests/"):
        return rel.startswith("tests/exercises/") and not is_hidden(rel)
    return True


def is_hidden(rel: str) -> bool:
    """A hidden test (``test_*_hidden.py``) or a hidden fixture (``fixtures/*_hidden.npz``)."""
    return pathlib.PurePosixPath(rel).stem.endswith("_hidden")


def where(name: str) -> str:
    return "EXERCISES.md, section %s" % name


def module_path(root, module: str) -> pathlib.Path:
    base = pathlib.Path(root).joinpath(*module.split("."))
    for cand in (base.with_suffix(".py"), base / "__init__.py"):
        if cand.exists():
            return cand
    raise BuildError("module %s not found under %s" % (module, root))


def split_target(target: str):
    module, _, qualname = target.partition(":")
    if not module or not qualname:
        raise BuildError("target %r is not 'module:qualname'" % target)
    return module, qualname


# ---------------------------------------------------------------------------------------------- ast helpers
def find_function(tree: ast.Module, qualname: str):
    """The FunctionDef of ``qualname`` (``f`` or ``Class.method``) at module level."""
    scope, node = tree.body, None
    for part in qualname.split("."):
        node = next((n for n in scope if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
                     and n.name == part), None)
        if node is None:
            return None
        scope = node.body
    return node if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) else None


def body_span(node, lines):
    """(first, last) 1-based line numbers of the function body after its docstring, comments included."""
    first_stmt = node.body[0]
    if isinstance(first_stmt, ast.Expr) and isinstance(getattr(first_stmt, "value", None), ast.Constant) \
            and isinstance(first_stmt.value.value, str):
        if len(node.body) == 1:
            return first_stmt.end_lineno + 1, first_stmt.end_lineno   # docstring only: empty span
        return first_stmt.end_lineno + 1, node.end_lineno
    i = node.lineno - 1                               # find the line that ends the signature (its colon)
    while i < first_stmt.lineno - 1 and not lines[i].split("#")[0].rstrip().endswith(":"):
        i += 1
    if first_stmt.lineno == node.lineno:
        raise BuildError("cannot replace the body of %s: it is on the signature line" % node.name)
    return i + 2, node.end_lineno


def body_indent(node, lines) -> str:
    line = lines[node.body[0].lineno - 1]          # the docstring, or the first statement
    return line[:len(line) - len(line.lstrip())]


def _has_docstring(node) -> bool:
    s = node.body[0]
    return isinstance(s, ast.Expr) and isinstance(getattr(s, "value", None), ast.Constant) \
        and isinstance(s.value.value, str)


def _locate_body(path: pathlib.Path, qualname: str):
    """(source lines of ``path``, the function node of ``qualname``, first and last line of its body)."""
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines(keepends=True)
    node = find_function(ast.parse(text), qualname)
    if node is None:
        raise BuildError("%s: no function %s" % (path, qualname))
    first, last = body_span(node, lines)
    return lines, node, first, last


def replace_body(path: pathlib.Path, qualname: str, new_body: str) -> str:
    """Replace the body of ``qualname`` in ``path`` by ``new_body`` (dedented text); returns the old body."""
    lines, node, first, last = _locate_body(path, qualname)
    indent = body_indent(node, lines)
    old = "".join(lines[first - 1:last])
    body = textwrap.indent(textwrap.dedent(new_body).strip("\n") + "\n", indent)
    lines[first - 1:last] = [body]
    path.write_text("".join(lines), encoding="utf-8")
    return old


def function_body_source(path: pathlib.Path, qualname: str) -> str:
    lines, _, first, last = _locate_body(path, qualname)
    return textwrap.dedent("".join(lines[first - 1:last]))


def stub_body(name: str) -> str:
    return "raise ExerciseNotImplemented(%r, %r)" % (name, where(name))


def is_stub(stmts: list) -> bool:
    """Whether a function's statements (its docstring left out) are the edition's stub: one
    ``raise ExerciseNotImplemented(...)``."""
    return (len(stmts) == 1 and isinstance(stmts[0], ast.Raise) and isinstance(stmts[0].exc, ast.Call)
            and getattr(stmts[0].exc.func, "id", None) == "ExerciseNotImplemented")


def body_dump(path: pathlib.Path, qualname: str) -> str:
    """The body statements of ``qualname`` (docstring excluded) as an AST dump, for comparisons."""
    node = find_function(ast.parse(path.read_text(encoding="utf-8")), qualname)
    if node is None:
        raise BuildError("%s: no function %s" % (path, qualname))
    stmts = node.body[1:] if _has_docstring(node) else node.body
    return "\n".join(ast.dump(s) for s in stmts)


def add_import(path: pathlib.Path, root: pathlib.Path) -> None:
    """Make ``ExerciseNotImplemented`` a module-level name of ``path`` (after its docstring / __future__)."""
    text = path.read_text(encoding="utf-8")
    if "ExerciseNotImplemented = " in text or IMPORT_LINE in text:
        return
    tree = ast.parse(text)
    after = 0
    for stmt in tree.body:
        is_doc = isinstance(stmt, ast.Expr) and isinstance(getattr(stmt, "value", None), ast.Constant)
        is_future = isinstance(stmt, ast.ImportFrom) and stmt.module == "__future__"
        if (is_doc and after == 0) or is_future:
            after = stmt.end_lineno
        else:
            break
    rel = path.relative_to(root).as_posix()
    line = IMPORT_LINE_GRAPH if rel.startswith("helpers/graph/") else IMPORT_LINE
    lines = text.splitlines(keepends=True)
    lines[after:after] = [line + "\n"]
    path.write_text("".join(lines), encoding="utf-8")


# ---------------------------------------------------------------------------------------------- the tree
def tracked_files(root: pathlib.Path):
    """Paths (relative, posix) of the files to copy: git's tracked files and new files it does not ignore
    (read-only ``git ls-files``), or a walk outside a checkout."""
    if (root / ".git").exists() and shutil.which("git"):
        out = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=str(root),
                             capture_output=True, check=False)
        if out.returncode == 0:
            return sorted(p for p in out.stdout.decode("utf-8").split("\0") if p and (root / p).is_file())
    files = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if d not in SKIP_DIRS and not d.endswith(".egg-info"))
        for f in filenames:
            if not f.endswith((".pyc", ".pyo")):
                files.append(pathlib.Path(dirpath, f).relative_to(root).as_posix())
    return sorted(files)


MANIFEST = ".student-edition-files"


def remove_previous_build(dest: pathlib.Path) -> None:
    """Delete what an earlier build wrote into ``dest`` (the files its manifest lists, then the folders they leave
    empty) and nothing else: an instructor's .git, notes or other files there stay. A non-empty ``dest`` without
    a manifest was not made by this tool: refuse."""
    if not dest.exists():
        return
    manifest = dest / MANIFEST
    if not manifest.exists():
        if any(dest.iterdir()):
            raise BuildError("%s exists and was not built by tools/student.py (no %s): choose an empty or new "
                             "folder, or remove it yourself" % (dest, MANIFEST))
        return
    folders = set()
    for rel in manifest.read_text(encoding="utf-8").splitlines():
        path = dest / rel
        if rel and ".." not in pathlib.PurePosixPath(rel).parts and path.is_file():
            path.unlink()
            folders.update(path.parents)
    for folder in sorted((f for f in folders if dest in f.parents), key=lambda f: -len(f.parts)):
        cache = folder / "__pycache__"
        if cache.is_dir():
            shutil.rmtree(cache, ignore_errors=True)
        if folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()
    manifest.unlink()


def write_manifest(dest: pathlib.Path, written) -> None:
    """List the files this build wrote (relative paths), so that the next build removes exactly these."""
    (dest / MANIFEST).write_text("\n".join(sorted(set(written))) + "\n", encoding="utf-8")


def copy_tree(root: pathlib.Path, dest: pathlib.Path, remove) -> list:
    remove_previous_build(dest)
    copied = []
    for rel in tracked_files(root):
        if not shipped(rel, remove):
            continue
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(root / rel, target)
        copied.append(rel)
    return copied


def redact(dest: pathlib.Path, entry: dict) -> None:
    path = dest / entry["file"]
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    starts = [i for i, ln in enumerate(lines) if ln.rstrip("\n").rstrip() == entry["after"].rstrip()]
    if len(starts) != 1:
        raise BuildError("redact: %r occurs %d times in %s" % (entry["after"], len(starts), entry["file"]))
    end = next((j for j in range(starts[0] + 1, len(lines)) if lines[j].startswith(entry["until"])), None)
    if end is None:
        raise BuildError("redact: %r not found after %r in %s" % (entry["until"], entry["after"], entry["file"]))
    lines[starts[0] + 1:end] = [entry["text"]]
    path.write_text("".join(lines), encoding="utf-8")


def replace_notebook_cells(dest: pathlib.Path, reg: dict) -> None:
    """The registry's ``notebook_cell`` entries: the source of the cell with that id replaced (outputs are
    stripped later with the others)."""
    for entry in reg["edition"].get("notebook_cell", []):
        path = dest / entry["notebook"]
        if not path.exists():
            raise BuildError("notebook_cell: no notebook %s" % entry["notebook"])
        nb = json.loads(path.read_text(encoding="utf-8"))
        cells = [c for c in nb.get("cells", []) if c.get("id") == entry["cell"]]
        if len(cells) != 1:
            raise BuildError("notebook_cell: %s has %d cells with id %r"
                             % (entry["notebook"], len(cells), entry["cell"]))
        cells[0]["source"] = lines_of(entry["source"].strip("\n"))
        path.write_text(json.dumps(nb, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")


def check_kept(root: pathlib.Path, reg: dict) -> None:
    """Every ``kept`` entry names an existing function of the answer key and an exercise of the registry."""
    names = {ex["name"] for ex in reg["exercise"]}
    for entry in reg["edition"].get("kept", []):
        module, qualname = split_target(entry["target"])
        if find_function(ast.parse(module_path(root, module).read_text(encoding="utf-8")), qualname) is None:
            raise BuildError("kept: %s names no function (update tools/exercises.toml)" % entry["target"])
        if entry.get("exercise") not in names or not entry.get("why"):
            raise BuildError("kept: %s needs an exercise of the registry and a why" % entry["target"])


def stub_targets(dest: pathlib.Path, reg: dict) -> None:
    for ex in reg["exercise"]:
        for target in ex["targets"]:
            module, qualname = split_target(target)
            path = module_path(dest, module)
            replace_body(path, qualname, stub_body(ex["name"]))
            add_import(path, dest)
    for entry in reg["edition"].get("rewrite", []):
        module, qualname = split_target(entry["target"])
        replace_body(module_path(dest, module), qualname, entry["body"])
    for entry in reg["edition"].get("redact", []):
        redact(dest, entry)
    replace_notebook_cells(dest, reg)


def build(dest=None, root=ROOT, quiet=False) -> pathlib.Path:
    root = pathlib.Path(root)
    dest = pathlib.Path(dest) if dest else root / "build" / "student"
    reg = load_registry(root)
    check_kept(root, reg)
    copied = copy_tree(root, dest, reg["edition"].get("remove", []))
    stub_targets(dest, reg)
    write_docs(root, dest, reg)
    write_manifest(dest, copied + ["EXERCISES.md", "README.md"])
    problems = self_check(dest, root, reg)
    if problems:
        raise BuildError("self-check failed:\n  " + "\n  ".join(problems))
    if not quiet:
        print("student edition in %s: %d files, %d exercises (%d functions stubbed); self-check passed"
              % (dest, len(copied), len(reg["exercise"]), sum(len(e["targets"]) for e in reg["exercise"])))
    return dest


# ---------------------------------------------------------------------------------------------- self-check
def solution_lines(root: pathlib.Path, reg: dict) -> dict:
    """{stripped line: exercise} for the distinctive lines of every answer-key solution body: at least
    MIN_LEAK_CHARS long and not also a line of the code the student edition keeps (argument checks and idioms
    shared with other functions reveal nothing; docstrings do not count as kept code)."""
    out = {}
    common = kept_code_lines(root, reg)
    for ex in reg["exercise"]:
        for target in ex["targets"]:
            module, qualname = split_target(target)
            for ln in function_body_source(module_path(root, module), qualname).splitlines():
                s = ln.strip()
                if len(s) >= MIN_LEAK_CHARS and s not in common:
                    out.setdefault(s, ex["name"])
    return out


def fast_path_lines(root: pathlib.Path, reg: dict) -> dict:
    """{stripped line: "fast path <where>"} for the distinctive lines of the answer key's fast paths: the original
    bodies of the ``rewrite`` targets and the removed modules under helpers/ (e.g. the compiled JCBB search), with
    the same rule as :func:`solution_lines` (long enough, not a line of the code the edition keeps, nor of the
    registry's own replacement texts: an argument check or a constant a rewrite keeps on purpose)."""
    out = {}
    edition = reg["edition"]
    texts = [e["body"] for e in edition.get("rewrite", [])] + [e["text"] for e in edition.get("redact", [])]
    common = kept_code_lines(root, reg) | {ln.strip() for t in texts for ln in t.splitlines()}
    sources = [("fast path " + r["target"], function_body_source(module_path(root, split_target(r["target"])[0]),
                                                                  split_target(r["target"])[1]))
               for r in reg["edition"].get("rewrite", [])]
    sources += [("fast path " + rel, (root / rel).read_text(encoding="utf-8"))
                for rel in reg["edition"].get("remove", [])
                if rel.startswith("helpers/") and rel.endswith(".py") and (root / rel).is_file()]
    for label, text in sources:
        for ln in text.splitlines():
            s = ln.strip()
            if len(s) >= MIN_LEAK_CHARS and s not in common:
                out.setdefault(s, label)
    return out


def kept_code_lines(root: pathlib.Path, reg: dict) -> set:
    """Stripped lines of the answer key's Python code that the student edition keeps: every copied .py file
    without the exercise and rewrite bodies and without docstrings."""
    removed = {}
    for target in [t for ex in reg["exercise"] for t in ex["targets"]] + \
            [r["target"] for r in reg["edition"].get("rewrite", [])]:
        module, qualname = split_target(target)
        removed.setdefault(module_path(root, module).resolve(), []).append(qualname)
    skip = reg["edition"].get("remove", [])
    lines = set()
    for rel in tracked_files(root):
        if not rel.endswith(".py") or not shipped(rel, skip):
            continue
        path = root / rel
        text = path.read_text(encoding="utf-8")
        src = text.splitlines()
        drop = set()
        tree = ast.parse(text)
        for qualname in removed.get(path.resolve(), []):
            first, last = body_span(find_function(tree, qualname), src)
            drop.update(range(first, last + 1))
        for node in [tree] + [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                                            ast.ClassDef))]:
            if node.body and _has_docstring(node):
                drop.update(range(node.body[0].lineno, node.body[0].end_lineno + 1))
        lines.update(ln.strip() for n, ln in enumerate(src, 1) if n not in drop)
    return lines


def self_check(dest: pathlib.Path, root: pathlib.Path, reg: dict) -> list:
    """Problems found in the student tree ``dest`` (empty list: it passed)."""
    problems = []
    for ex in reg["exercise"]:
        stub = "\n".join(ast.dump(s) for s in ast.parse(stub_body(ex["name"])).body)
        for target in ex["targets"]:
            module, qualname = split_target(target)
            if body_dump(module_path(dest, module), qualname) != stub:
                problems.append("%s: the body of %s is not the stub" % (ex["name"], target))
    leaks = {}
    leaks.update((ln, "the " + where) for ln, where in fast_path_lines(root, reg).items())
    leaks.update((ln, "the solution of " + ex) for ln, ex in solution_lines(root, reg).items())
    for path in sorted(dest.rglob("*")):
        if path.suffix not in (".py", ".ipynb") or any(p in SKIP_DIRS for p in path.relative_to(dest).parts):
            continue
        text = path.read_text(encoding="utf-8")
        if path.suffix == ".ipynb":
            text = "\n".join(_notebook_strings(json.loads(text)))
        for n, ln in enumerate(text.splitlines(), 1):
            ex = leaks.get(ln.strip())
            if ex is not None:
                problems.append("%s:%d shows a line of %s: %s"
                                % (path.relative_to(dest).as_posix(), n, ex, ln.strip()[:80]))
    return problems + edition_problems(dest, root)


MIN_ANSWER_CHARS = 30


def answer_lines(root: pathlib.Path) -> set:
    """Distinctive lines (≥ MIN_ANSWER_CHARS, stripped) of the answer key's answer cells that no other cell of
    its notebooks has (a heading or a phrase the teaching text also uses reveals nothing)."""
    answers, others = set(), set()
    for path in sorted((root / "notebooks").glob("*.ipynb")):
        for cell in json.loads(path.read_text(encoding="utf-8")).get("cells", []):
            tags = cell.get("metadata", {}).get("tags", [])
            lines = {ln.strip() for ln in "".join(cell.get("source", [])).splitlines()}
            (answers if "answer" in tags else others).update(ln for ln in lines if len(ln) >= MIN_ANSWER_CHARS)
    return answers - others


def edition_problems(dest: pathlib.Path, root: pathlib.Path) -> list:
    """What must never reach the edition: hidden tests and fixtures, the answer key's own tests, notebook cells
    tagged ``answer`` or ``check``, and any line of an answer cell (in a notebook, a Markdown or a Python file)."""
    problems = []
    for path in sorted(dest.rglob("*")):
        rel = path.relative_to(dest).as_posix()
        if any(p in SKIP_DIRS for p in path.relative_to(dest).parts) or not path.is_file():
            continue
        if rel.startswith("tests/") and not shipped(rel, ()):
            problems.append("%s: a hidden test or fixture, or an answer-key test, is in the edition" % rel)
    leaks = answer_lines(root)
    for path in sorted(dest.rglob("*")):
        if path.suffix not in (".ipynb", ".md", ".py") or any(p in SKIP_DIRS for p in path.relative_to(dest).parts):
            continue
        text = path.read_text(encoding="utf-8")
        if path.suffix == ".ipynb":
            nb = json.loads(text)
            for cell in nb.get("cells", []):
                tags = set(cell.get("metadata", {}).get("tags", [])) & {"answer", "check"}
                if tags:
                    problems.append("%s: cell %s tagged %s" % (path.relative_to(dest).as_posix(), cell.get("id"),
                                                              sorted(tags)))
            text = "\n".join(_notebook_strings(nb))
        for n, ln in enumerate(text.splitlines(), 1):
            if ln.strip() in leaks:
                problems.append("%s:%d shows a line of an answer cell: %s"
                                % (path.relative_to(dest).as_posix(), n, ln.strip()[:80]))
    return problems


def _notebook_strings(nb: dict):
    for cell in nb.get("cells", []):
        yield "".join(cell.get("source", []))
        for out in cell.get("outputs", []):
            yield "".join(out.get("text", []))
            for value in out.get("data", {}).values():
                if isinstance(value, (list, str)):
                    yield "".join(value)


# ---------------------------------------------------------------------------------------------- solutions
def copy_solution(student: pathlib.Path, name: str, root: pathlib.Path = ROOT) -> None:
    """Put the answer key's bodies of exercise ``name`` into the student tree (what a correct student writes)."""
    reg = load_registry(root)
    ex = next((e for e in reg["exercise"] if e["name"] == name), None)
    if ex is None:
        raise BuildError("no exercise %r in %s" % (name, REGISTRY))
    for target in ex["targets"]:
        module, qualname = split_target(target)
        replace_body(module_path(student, module), qualname,
                     function_body_source(module_path(root, module), qualname))


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    try:
        if argv[:1] == ["build"]:
            build(argv[1] if len(argv) > 1 else None)
        elif argv[:1] == ["check"] and len(argv) == 2:
            problems = self_check(pathlib.Path(argv[1]), ROOT, load_registry())
            print("\n".join(problems) if problems else "self-check passed")
            return 1 if problems else 0
        elif argv[:1] == ["clean"] and len(argv) == 2:
            remove_previous_build(pathlib.Path(argv[1]))
        elif argv[:1] == ["copy-solution"] and len(argv) == 3:
            copy_solution(pathlib.Path(argv[1]), argv[2])
        else:
            print(__doc__)
            return 2
    except BuildError as err:
        print("error: %s" % err, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
