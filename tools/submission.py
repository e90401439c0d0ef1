"""Pack the student's work into one zip to hand in (``make submission``; Windows: ``py tools\\workbook.py submission``).

    python tools/submission.py [OUT]          # default: submission.zip in the workbook's folder

The zip holds, at their paths in the workbook, the Python files that contain exercise functions (the registry
``tools/exercises.toml`` names them) and every notebook (``notebooks/*.ipynb``: the answer cells are in them).
Nothing else: the grader takes only the exercise functions (with any helper function written next to them in
the same file) and the answer cells, and grades them in its own copy of the workbook. It prints which exercises
are still the stub and how many answer cells are empty, so nothing is handed in by mistake.
Standard library only; runs on every platform.
"""
from __future__ import annotations

import ast
import json
import pathlib
import sys
import tomllib
import zipfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
PROMPT = "*Your answer:*"                 # the edition's answer cells start with these (tools/student_docs.py)
PROMPT_NOTE = "(write it in this cell, and keep the cell where it is)"
CODE_PROMPT = "# your answer (code)"


def answer_text(text: str) -> str:
    """A ``student-answer`` cell's answer: its text without the edition's prompt ("" when nothing is written). The
    one rule for "answered", here and in the instructor's grader."""
    text = text.strip()
    if text == CODE_PROMPT:
        return ""
    if text.startswith(PROMPT):
        text = text[len(PROMPT):].strip()
        if text.startswith(PROMPT_NOTE):
            text = text[len(PROMPT_NOTE):].strip()
    return text


def exercise_files(root: pathlib.Path = ROOT) -> dict:
    """{repo-relative .py path: [(exercise, qualname), ...]} from the registry's targets."""
    with open(root / "tools" / "exercises.toml", "rb") as fh:
        reg = tomllib.load(fh)
    files = {}
    for ex in reg["exercise"]:
        for target in ex["targets"]:
            module, _, qualname = target.partition(":")
            base = pathlib.PurePosixPath(*module.split("."))
            rel = base.with_suffix(".py") if (root / base.with_suffix(".py")).exists() else base / "__init__.py"
            files.setdefault(rel.as_posix(), []).append((ex["name"], qualname))
    return files


def _function(tree: ast.Module, qualname: str):
    scope, node = tree.body, None
    for part in qualname.split("."):
        node = next((n for n in scope if isinstance(n, (ast.FunctionDef, ast.ClassDef)) and n.name == part), None)
        if node is None:
            return None
        scope = node.body
    return node


def unwritten(root: pathlib.Path, files: dict) -> list:
    """The exercises whose target body is still only the stub's ``raise ExerciseNotImplemented(...)``."""
    out = []
    for rel, targets in files.items():
        tree = ast.parse((root / rel).read_text(encoding="utf-8"))
        for name, qualname in targets:
            node = _function(tree, qualname)
            body = [s for s in (node.body if node else []) if not (isinstance(s, ast.Expr)
                                                                    and isinstance(s.value, ast.Constant))]
            if node is None or (len(body) == 1 and isinstance(body[0], ast.Raise)
                                and "ExerciseNotImplemented" in ast.dump(body[0])):
                out.append(name)
    return sorted(set(out))


def empty_answers(root: pathlib.Path) -> tuple[int, int]:
    """(empty, all) answer cells (tag ``student-answer``) over the notebooks."""
    empty = total = 0
    for path in sorted((root / "notebooks").glob("*.ipynb")):
        for cell in json.loads(path.read_text(encoding="utf-8")).get("cells", []):
            if "student-answer" in cell.get("metadata", {}).get("tags", []):
                total += 1
                source = cell.get("source", [])
                empty += not answer_text("".join(source) if isinstance(source, list) else str(source))
    return empty, total


def pack(out: pathlib.Path, root: pathlib.Path = ROOT) -> list:
    """Write the zip; returns the paths it holds."""
    files = sorted(exercise_files(root)) + sorted(p.relative_to(root).as_posix()
                                                  for p in (root / "notebooks").glob("*.ipynb"))
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for rel in files:
            zf.write(root / rel, rel)
    return files


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = pathlib.Path(argv[0]) if argv else ROOT / "submission.zip"
    files = exercise_files(ROOT)
    for rel in files:
        try:
            ast.parse((ROOT / rel).read_text(encoding="utf-8"))
        except SyntaxError as err:
            print("error: %s does not parse (line %s: %s): fix it before handing in" % (rel, err.lineno, err.msg))
            return 1
    packed = pack(out, ROOT)
    todo = unwritten(ROOT, files)
    empty, total = empty_answers(ROOT)
    print("wrote %s: %d files (%d exercise files, %d notebooks)"
          % (out, len(packed), len(files), len(packed) - len(files)))
    print("exercises still the stub: %s" % (", ".join(todo) if todo else "none"))
    print("answer cells still empty: %d of %d" % (empty, total))
    return 0


if __name__ == "__main__":
    sys.exit(main())
