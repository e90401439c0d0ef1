"""What the grader takes from a submission zip: the student's exercise bodies (with the helper functions they added
next to them) and their written answers. Nothing in a zip is extracted, imported or run here.

A submission is ``<student id>.zip`` (``make submission``): the module files that hold exercise targets at their
repository-relative paths, and ``notebooks/*.ipynb``. Module files are read as text (a member with ``..`` or an
absolute path is ignored; at most MAX_FILE_BYTES each) and parsed with ``ast``; ``merge_submission`` writes each
target's body into the grading tree's stub, plus the module-level functions the student ADDED to that file (names
the answer key's module does not define). Notebooks are read as JSON, only for the ``student-answer`` cells.
"""
from __future__ import annotations

import ast
import json
import pathlib
import re
import shutil
import sys
import tempfile
import textwrap
import zipfile
import zlib

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import student  # noqa: E402  (the answer key's builder: registry, ast helpers)

ROOT = student.ROOT
MAX_FILE_BYTES = 2_000_000          # of one module file read from a zip
MAX_ANSWER_CHARS = 60_000           # of one written answer


def exercise_files(reg: dict, root=ROOT) -> dict:
    """{exercise name: [(repo-relative posix path of the module, qualname), ...]} for every target."""
    out = {}
    for ex in reg["exercise"]:
        for target in ex["targets"]:
            module, qualname = student.split_target(target)
            rel = student.module_path(root, module).relative_to(root).as_posix()
            out.setdefault(ex["name"], []).append((rel, qualname))
    return out


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
            except (UnicodeDecodeError, zipfile.BadZipFile, zlib.error, OSError, RuntimeError, ValueError) as err:
                problems[rel] = "%s cannot be read: %s" % (rel, err)
                continue
            sources[rel] = text
    return sources, problems


def answer_cells(root=ROOT) -> list:
    """The answer cells of the tree at ``root`` (tag ``answer`` in the answer key, ``student-answer`` in the student
    edition or a grading tree; same ids): [{"notebook", "cell", "question"}], in notebook order."""
    out = []
    for path in sorted((pathlib.Path(root) / "notebooks").glob("*.ipynb")):
        for cell in json.loads(path.read_text(encoding="utf-8")).get("cells", []):
            meta = cell.get("metadata", {})
            if {"answer", "student-answer"} & set(meta.get("tags", [])):
                out.append({"notebook": "notebooks/" + path.name, "cell": cell.get("id"),
                            "question": " ".join(str(meta.get("question", "")).split())})
    return out


def read_answers(zip_path: pathlib.Path, wanted: list) -> list:
    """The student's written answers: for each answer cell of the answer key (``wanted`` = answer_cells()), the
    cell with the same id in the submitted notebook (tag ``student-answer``), as text. Only ``notebooks/*.ipynb``
    members are read, as JSON; the question is the answer key's. Status: answered, unanswered (the prompt as the
    edition left it, or empty), or missing (no such notebook or cell, or a notebook that is not JSON)."""
    import submission

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
                    except (ValueError, AttributeError, zipfile.BadZipFile, zlib.error, OSError, RuntimeError):
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
            text = ("".join(source) if isinstance(source, list) else str(source))[:MAX_ANSWER_CHARS].strip()
            entry.update(answer=text, status="answered" if submission.answer_text(text) else "unanswered")
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


def is_stub(body: str) -> bool:
    """Whether a function body (its source) is the student edition's stub: one ``raise ExerciseNotImplemented(...)``
    (after the docstring, if any)."""
    try:
        stmts = ast.parse(textwrap.dedent(body)).body
    except SyntaxError:
        return False
    if stmts and isinstance(stmts[0], ast.Expr) and isinstance(stmts[0].value, ast.Constant):
        stmts = stmts[1:]
    return student.is_stub(stmts)


def merge_submission(tree: pathlib.Path, sources: dict, files: dict, root=ROOT) -> dict:
    """Write the student's bodies of every target (and their added helpers) into ``tree``.
    ``files`` = exercise_files(); returns {exercise: reason} for exercises that cannot be graded (their stubs stay)."""
    problems = {}
    scratch = pathlib.Path(tempfile.mkdtemp(prefix="student-src-"))
    try:
        for name, targets in files.items():
            stubs = 0
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
                    stubs += is_stub(body)
                    student.replace_body(dest, qualname, body)
                    ast.parse(dest.read_text(encoding="utf-8"))
                except (student.BuildError, SyntaxError, ValueError) as err:
                    dest.write_text(before, encoding="utf-8")
                    problems[name] = "%s: cannot take %s from it: %s" % (
                        rel, qualname, str(err).replace(str(src_file), rel))
            if stubs == len(targets):                   # nothing written: no need to run its checks
                problems.setdefault(name, "not written yet (%s still the stub)" % ", ".join(q for _, q in targets))
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
