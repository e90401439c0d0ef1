"""The student edition's documents and notebooks (used by ``tools/student.py``; standard library only).

- ``EXERCISES.md``: every exercise's task, where to write it, the tests that grade it, the notebooks that run it;
- ``README.md``: the answer key's README with a student-edition preface (how to work) instead of its title;
- notebooks: outputs stripped except the kept ones, a cell after the title naming the exercises the notebook
  runs, and ``import helpers.exercises`` (short messages for unimplemented exercises) in the first code cell.
"""
from __future__ import annotations

import json
import pathlib

NOTEBOOK_IMPORT = "import helpers.exercises  # short messages for unimplemented exercises"
EXERCISE_CELL_ID = "student-edition-exercises"


def _target_text(target: str) -> str:
    module, _, qualname = target.partition(":")
    return "`%s` in `%s`" % (qualname, module.replace(".", "/") + ".py")


def _notebook_exercises(reg: dict) -> dict:
    """{notebook stem: [exercise, ...]} from the registry's per-exercise notebook lists."""
    out = {}
    for ex in reg["exercise"]:
        for stem in ex["notebooks"]:
            out.setdefault(stem, []).append(ex)
    return out


def exercises_markdown(reg: dict) -> str:
    lines = ["# Exercises", "",
             "This is the student edition of the SLAM course workbook. Each exercise below is a function (or a "
             "few) whose body you write; until you do, it raises `ExerciseNotImplemented` naming the exercise. "
             "Work on one exercise at a time:", "",
             "1. read its task here (the course document's part is named, so you can read the full text there);",
             "2. write the body of the function(s) listed under *Where*: keep the signature, read the docstring;",
             "3. grade it: `make grade EX=<name>` (Windows: `py -3.12 tools\\workbook.py grade <name>`); the line "
             "of the exercise says `passed`, or the first check that failed;",
             "4. run the notebooks listed under *Notebooks*: they now run your code.", "",
             "`make grade` alone grades every exercise and ends with `exercises: N passed, M failed` and "
             "`other tests: K passed, L failed` (the rest of the workbook's tests; they pass from the start). "
             "Where an exercise's tests also call other exercises, those are listed under *Needs*: do them first.",
             "", "Where the answer key has a fast version of an exercise (vectorised, compiled or batched), this "
             "edition calls your function in its place, so every notebook and every other function that uses it "
             "runs your code: `tools/exercises.toml` lists these under `[[edition.rewrite]]`, each with the reason.",
             "", "| exercise | course document, part |", "|---|---|"]
    for ex in reg["exercise"]:
        lines.append("| [`%s`](#%s) | %s |" % (ex["name"], ex["name"], ex["source"]))
    for ex in reg["exercise"]:
        lines += ["", "## %s" % ex["name"], "", "**%s.**" % ex["source"], "",
                  " ".join(ex["task"].split()), "",
                  "*Where:* " + "; ".join(_target_text(t) for t in ex["targets"]) + ".", "",
                  "*Tests* (`make grade EX=%s`): " % ex["name"]
                  + ", ".join("`%s`" % t for t in ex["tests"]) + "."]
        if ex["needs"]:
            lines += ["", "*Needs:* " + ", ".join("`%s`" % n for n in ex["needs"]) + "."]
        lines += ["", "*Notebooks:* " + (", ".join("`notebooks/%s.ipynb`" % n for n in ex["notebooks"])
                                          if ex["notebooks"] else "none (graded by its tests only)") + "."]
    return "\n".join(lines) + "\n"


def student_readme(original: str, reg: dict) -> str:
    body = original.split("\n", 1)[1] if original.startswith("# ") else original
    start = body.find("\n## Benchmarks")
    if start >= 0:                                    # benchmarks/ is not part of the student edition
        end = body.find("\n## ", start + 1)
        body = body[:start] + (body[end:] if end >= 0 else "\n")
    preface = [
        "# SLAM course workbook — student edition", "",
        "This tree is the workbook with **%d exercises** left for you: their functions raise "
        "`ExerciseNotImplemented` until you write them. **Start with `EXERCISES.md`**: it gives each task, the "
        "file and function to write, the tests that grade it and the notebooks that use it." % len(reg["exercise"]),
        "", "How to work:", "",
        "1. `make setup` (or any task below) creates `.venv` exactly as in the answer key;",
        "2. read an exercise in `EXERCISES.md` and write its function body;",
        "3. `make grade EX=<name>` grades that exercise (`make grade` grades all of them; Windows: "
        "`py -3.12 tools\\workbook.py grade [name]`);",
        "4. run the notebooks that use it (`make lab`): a cell that needs an exercise you have not written stops "
        "with a one-line message naming it; once it is written, the notebooks run on your code.", "",
        "In this edition `make test` runs the grader (it fails only if a test outside the exercises fails) and then "
        "nbval in lax mode over the notebooks whose exercises all pass. The notebooks ship without stored outputs, "
        "except the few that show what a correct result looks like (Lab 8's console output and Figure 1) and the "
        "notebooks that use no exercise.", ""]
    return "\n".join(preface) + body


def student_notebook(nb: dict, exercises, keep) -> dict:
    """Strip outputs (except ``keep``: a set of cell ids, or {"*"}), add the exercise cell and the import."""
    for cell in nb["cells"]:
        if cell.get("cell_type") != "code":
            continue
        tags = cell.get("metadata", {}).get("tags", [])
        if "*" not in keep and cell.get("id") not in keep and "keep-output" not in tags:
            cell["outputs"] = []
            cell["execution_count"] = None
    first_code = next((c for c in nb["cells"] if c.get("cell_type") == "code"), None)
    if first_code is not None:
        src = "".join(first_code.get("source", []))
        if NOTEBOOK_IMPORT not in src:
            first_code["source"] = lines_of(NOTEBOOK_IMPORT + "\n" + src)
    if exercises and not any(c.get("id") == EXERCISE_CELL_ID for c in nb["cells"]):
        text = ["**Student edition.** This notebook runs your code for these exercises (tasks in `EXERCISES.md`):", ""]
        text += ["- `%s` (%s): %s" % (ex["name"], ex["source"], "; ".join(_target_text(t) for t in ex["targets"]))
                 for ex in exercises]
        text += ["", "A cell that needs an exercise you have not written yet stops with a short message naming it. "
                     "Check an exercise with `make grade EX=<name>`."]
        cell = {"cell_type": "markdown", "id": EXERCISE_CELL_ID, "metadata": {}, "source": lines_of("\n".join(text))}
        at = 1 if nb["cells"] and nb["cells"][0].get("cell_type") == "markdown" else 0
        nb["cells"].insert(at, cell)
    return nb


def lines_of(text: str):
    """A notebook cell's source list (one string per line, newlines kept) from text."""
    parts = text.split("\n")
    return [p + "\n" for p in parts[:-1]] + ([parts[-1]] if parts[-1] else [])


def write_docs(root: pathlib.Path, dest: pathlib.Path, reg: dict) -> None:
    (dest / "EXERCISES.md").write_text(exercises_markdown(reg), encoding="utf-8")
    readme = pathlib.Path(root) / "README.md"
    if readme.exists():
        (dest / "README.md").write_text(student_readme(readme.read_text(encoding="utf-8"), reg), encoding="utf-8")
    keep = {}
    for entry in reg["edition"].get("keep_outputs", []):
        keep.setdefault(pathlib.PurePosixPath(entry["notebook"]).stem, set()).update(entry["cells"])
    by_notebook = _notebook_exercises(reg)
    for path in sorted((dest / "notebooks").glob("*.ipynb")):
        nb = json.loads(path.read_text(encoding="utf-8"))
        nb = student_notebook(nb, by_notebook.get(path.stem, []), keep.get(path.stem, set()))
        path.write_text(json.dumps(nb, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
