"""The student edition's documents and notebooks (used by ``tools/student.py``; standard library only).

- ``EXERCISES.md``: every exercise's task, where to write it, the tests that grade it, the notebooks that run it;
- ``README.md``: the answer key's README with a student-edition preface (how to work) instead of its title;
- notebooks: outputs stripped except the kept ones, a cell after the title naming the exercises the notebook
  runs, and ``import helpers.exercises`` (short messages for unimplemented exercises) in the first code cell.
"""
from __future__ import annotations

import json
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import submission  # noqa: E402  (the answer cells' prompt, and what counts as answered)

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
             "Each exercise below is a function (or a few) whose body you write; until you do, it raises "
             "`ExerciseNotImplemented` naming the exercise. Every exercise stands alone: its checks call only your "
             "function, so you can do them in any order (a notebook needs the exercises it teaches and those of "
             "the earlier notebooks of its part). For each one:", "",
             "1. read its task here (the course document's part is named: read the full text there);",
             "2. write the body of the function(s) under *Where*: keep the signature, read the docstring;",
             "3. check it: `make grade EX=<name>` (Windows: `py tools\\workbook.py grade <name>`), a few "
             "seconds: it says `passed`, or shows each failed check with the input, the expected and the actual "
             "value and a hint;",
             "4. run the notebooks under *Notebooks*: they now run your code.", "",
             "`make grade` checks every exercise and ends with `exercises: N passed, M failed`.",
             "", "| exercise | course document, part |", "|---|---|"]
    for ex in reg["exercise"]:
        lines.append("| [`%s`](#%s) | %s |" % (ex["name"], ex["name"], ex["source"]))
    for ex in reg["exercise"]:
        lines += ["", "## %s" % ex["name"], "", "**%s.**" % ex["source"], "",
                  " ".join(ex["task"].split()), "",
                  "*Where:* " + "; ".join(_target_text(t) for t in ex["targets"]) + ".", "",
                  "*Check it:* `make grade EX=%s` runs `tests/exercises/test_%s.py` (it calls only this "
                  "exercise; the instructor's grader adds hidden value checks)." % (ex["name"], ex["name"])]
        lines += ["", "*Notebooks:* " + (", ".join("`notebooks/%s.ipynb`" % n for n in ex["notebooks"])
                                          if ex["notebooks"] else "none (graded by its tests only)") + "."]
    return "\n".join(lines) + "\n"


def student_readme(template: str, reg: dict) -> str:
    """The student README: tools/student_readme.md (for students: set-up, how to work, grade, answer) with the
    number of exercises filled in. The answer key's README (maintainers: CI, nbval, benchmarks) is not copied."""
    return template.replace("{n}", str(len(reg["exercise"])))


ANSWER_PROMPT = "%s %s" % (submission.PROMPT, submission.PROMPT_NOTE)


def question_cells(cell: dict) -> list:
    """An answer cell of the answer key (tag ``answer``, metadata ``question``) becomes the course's question and
    an empty cell for the student's answer (tag ``student-answer``; it keeps the answer cell's id, so a grader can
    find the student's answer)."""
    meta = cell.get("metadata", {})
    question = meta.get("question")
    if not question:
        raise ValueError("answer cell %s has no 'question' in its metadata" % cell.get("id"))
    ask = {"cell_type": "markdown", "id": "%s-question" % cell.get("id"), "metadata": {},
           "source": lines_of("**Question.** " + " ".join(question.split()))}
    answer = {"cell_type": cell["cell_type"], "id": cell.get("id"),
              "metadata": {"tags": ["student-answer"], "question": question}, "source": []}
    if cell["cell_type"] == "code":
        answer.update(outputs=[], execution_count=None, source=lines_of(submission.CODE_PROMPT + "\n"))
    else:
        answer["source"] = lines_of(ANSWER_PROMPT)
    return [ask, answer]


def student_notebook(nb: dict, exercises, keep) -> dict:
    """Drop the ``check`` cells, turn each ``answer`` cell into its question and an empty answer cell, strip
    outputs (except ``keep``: a set of cell ids, or {"*"}), add the exercise cell and the import."""
    cells = []
    for cell in nb["cells"]:
        tags = cell.get("metadata", {}).get("tags", [])
        if "check" in tags:
            continue
        if "answer" in tags:
            cells += question_cells(cell)
            continue
        cells.append(cell)
        if cell.get("cell_type") != "code":
            continue
        if "*" not in keep and cell.get("id") not in keep and "keep-output" not in tags:
            cell["outputs"] = []
            cell["execution_count"] = None
    nb["cells"] = cells
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
    template = pathlib.Path(root) / "tools" / "student_readme.md"
    (dest / "README.md").write_text(student_readme(template.read_text(encoding="utf-8"), reg), encoding="utf-8")
    keep = {}
    for entry in reg["edition"].get("keep_outputs", []):
        keep.setdefault(pathlib.PurePosixPath(entry["notebook"]).stem, set()).update(entry["cells"])
    by_notebook = _notebook_exercises(reg)
    for path in sorted((dest / "notebooks").glob("*.ipynb")):
        nb = json.loads(path.read_text(encoding="utf-8"))
        nb = student_notebook(nb, by_notebook.get(path.stem, []), keep.get(path.stem, set()))
        path.write_text(json.dumps(nb, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
