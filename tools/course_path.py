"""Measure the course path: the part of ``helpers`` that notebooks 00–21 and the exercises import.

The course path is the import closure (imports read from the source with ``ast``, those inside functions too; a
module's parent packages count, since importing ``helpers.graph.edge`` runs ``helpers/graph/__init__.py``) of

- every ``helpers`` import in the code cells of the course notebooks (00–21), and
- the modules of the exercise targets in ``tools/exercises.toml``.

It prints the targets of the readable-package issue: lines of the course path (docstrings and comments included),
modules over 400 lines, functions over 60 lines (a function's whole ``def``, docstring included), and the same for
the advanced part (the rest of ``helpers``) for comparison. ``--check`` exits 1 when a target is missed.

    python tools/course_path.py            # the table
    python tools/course_path.py --list     # and every module of the course path with its lines
    python tools/course_path.py --unhinted # and every public function of it without full type hints
"""
from __future__ import annotations

import argparse
import ast
import json
import pathlib
import re
import sys
import tomllib

ROOT = pathlib.Path(__file__).resolve().parents[1]
HELPERS = ROOT / "helpers"
COURSE_NOTEBOOKS = [p for p in sorted((ROOT / "notebooks").glob("*.ipynb")) if int(p.name[:2]) <= 21]
TARGET_LINES, MODULE_LINES, FUNCTION_LINES = 8000, 400, 60


def module_name(path: pathlib.Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {module_name(p): p for p in sorted(HELPERS.rglob("*.py"))}


def imported_modules(tree: ast.AST, package: str) -> set[str]:
    """The ``helpers`` modules an AST imports (``package`` resolves relative imports)."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.split(".")[0] == "helpers"}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[:len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "helpers":
                continue
            found.add(target)
            found |= {f"{target}.{a.name}" for a in node.names}
    return {m for m in found if m in MODULES}


def module_imports(name: str) -> set[str]:
    path = MODULES[name]
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    return imported_modules(ast.parse(path.read_text(encoding="utf-8")), package)


def notebook_imports(path: pathlib.Path) -> set[str]:
    found = set()
    for cell in json.loads(path.read_text(encoding="utf-8"))["cells"]:
        if cell["cell_type"] != "code":
            continue
        source = "".join(cell["source"])
        source = re.sub(r"^\s*[%!].*$", "", source, flags=re.M)       # IPython magics
        found |= imported_modules(ast.parse(source), "helpers")
    return found


def exercise_modules() -> set[str]:
    registry = tomllib.loads((ROOT / "tools" / "exercises.toml").read_text(encoding="utf-8"))
    return {t.split(":")[0] for ex in registry.get("exercise", []) for t in ex["targets"]}


def closure(roots: set[str]) -> set[str]:
    seen, todo = set(), list(roots)
    while todo:
        m = todo.pop()
        if m in seen or m not in MODULES:
            continue
        seen.add(m)
        parts = m.split(".")
        todo += [".".join(parts[:i]) for i in range(1, len(parts))]      # parent packages run first
        todo += module_imports(m)
    return seen


def long_functions(path: pathlib.Path, limit: int) -> list[tuple[str, int]]:
    out = []

    def walk(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = child.end_lineno - min([child.lineno] + [d.lineno for d in child.decorator_list]) + 1
                if n > limit:
                    out.append((prefix + child.name, n))
                walk(child, prefix + child.name + ".")
            elif isinstance(child, ast.ClassDef):
                walk(child, prefix + child.name + ".")
    walk(ast.parse(path.read_text(encoding="utf-8")), "")
    return out


def unhinted_functions(path: pathlib.Path) -> list[str]:
    """Public functions and methods (name without a leading underscore, in a public class; ``__init__`` counts)
    with a parameter other than self/cls, or a return, left unannotated (``__init__``'s return excepted)."""
    out = []

    def missing(f) -> bool:
        a = f.args
        params = a.posonlyargs + a.args + a.kwonlyargs + [p for p in (a.vararg, a.kwarg) if p]
        params = [p for p in params if p.arg not in ("self", "cls")]
        return any(p.annotation is None for p in params) or (f.returns is None and f.name != "__init__")

    def walk(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                public = not child.name.startswith("_") or child.name == "__init__"
                if public and missing(child):
                    out.append(prefix + child.name)
            elif isinstance(child, ast.ClassDef) and not child.name.startswith("_"):
                walk(child, prefix + child.name + ".")
    walk(ast.parse(path.read_text(encoding="utf-8")), "")
    return out


def lines(name: str) -> int:
    return len(MODULES[name].read_text(encoding="utf-8").splitlines())


def report(title: str, names: set[str]) -> dict:
    total = sum(lines(m) for m in names)
    big = sorted((lines(m), m) for m in names if lines(m) > MODULE_LINES)
    long = [(m, f, n) for m in sorted(names) for f, n in long_functions(MODULES[m], FUNCTION_LINES)]
    unhinted = [(m, f) for m in sorted(names) for f in unhinted_functions(MODULES[m])]
    print(f"{title}: {len(names)} modules, {total} lines")
    print(f"  modules over {MODULE_LINES} lines: {len(big)}" + "".join(f"\n    {m} ({n})" for n, m in big))
    print(f"  functions over {FUNCTION_LINES} lines: {len(long)}"
          + "".join(f"\n    {m}:{f} ({n})" for m, f, n in long))
    print(f"  public functions without full type hints: {len(unhinted)}"
          + (f" (first: {', '.join(m + ':' + f for m, f in unhinted[:5])})" if unhinted else ""))
    return {"lines": total, "big": big, "long": long, "unhinted": unhinted}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--list", action="store_true", help="list the course path's modules")
    parser.add_argument("--unhinted", action="store_true", help="list the course path's functions without hints")
    parser.add_argument("--check", action="store_true", help="exit 1 when a target is missed")
    args = parser.parse_args(argv)
    roots = set().union(*(notebook_imports(p) for p in COURSE_NOTEBOOKS)) | exercise_modules()
    course = closure(roots)
    course_report = report(f"course path (notebooks {COURSE_NOTEBOOKS[0].name[:2]}–{COURSE_NOTEBOOKS[-1].name[:2]}"
                           " and the exercises)", course)
    if args.list:
        for m in sorted(course):
            print(f"    {lines(m):5d}  {m}")
    if args.unhinted:
        for m, f in course_report["unhinted"]:
            print(f"    {m}:{f}")
    report("advanced part and the rest of helpers", set(MODULES) - course)
    print(f"target: course path ≤ {TARGET_LINES} lines, no module over {MODULE_LINES}, "
          f"no function over {FUNCTION_LINES}, type hints on every public function")
    missed = (course_report["lines"] > TARGET_LINES or course_report["big"] or course_report["long"]
              or course_report["unhinted"])
    return int(bool(args.check and missed))


if __name__ == "__main__":
    sys.exit(main())
