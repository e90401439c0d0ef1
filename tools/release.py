"""Release the course's model solutions into a student's tree, and gather written answers for marking by hand.

    python tools/release.py solutions TREE NAME [NAME ...] [--separate]   # = workbook.py release TREE NAME ...
    python tools/release.py answers SUBMISSIONS_DIR [--out DIR]  # = workbook.py answers SUBMISSIONS_DIR

``solutions``: TREE is a student edition (it has the ``.student-edition-files`` manifest of ``make student`` and
``helpers/``); NAME an exercise of ``tools/exercises.toml`` or a notebook (its number ``12`` or its stem).
An exercise: each target whose body in TREE is still the edition's stub (``raise ExerciseNotImplemented(...)``)
gets the answer key's body in place; a target the student wrote (or that TREE lacks or cannot parse) is not
touched, and the answer key's whole function goes to ``TREE/solutions/<exercise>.py``; one line per target says
which. A notebook: after each ``student-answer`` cell, a cell tagged ``model-answer`` (id: the answer cell's id +
``-model``) with the answer key's answer (code as code, without outputs); the student's cells are not changed and
a second run replaces the model cells. ``--separate`` (for the published edition, which students pull with git):
nothing of TREE changes but ``solutions/``: each exercise's model functions go to ``solutions/<exercise>.py`` and
each notebook's questions with their model answers to ``solutions/<notebook>_answers.md``, so a student's own
code and answers never conflict with the release. Everything is checked and prepared before the first file is
written, each file atomically; an unknown NAME, a TREE that is not an edition or a file that cannot be prepared:
a message, exit status 2, nothing written.

``answers``: the written answers of every ``<student id>.zip`` of SUBMISSIONS_DIR (read with
``submission_files.read_answers``: nothing is extracted or run) as one self-contained UTF-8 HTML page per answer
cell of the answer key, ``OUT/q01.html`` ... (question, notebook and cell, counts, then each student's answer and
status: answered, unanswered or missing), and ``OUT/index.html`` linking them (OUT defaults to
SUBMISSIONS_DIR/answers-html). A file that is not a readable zip counts as missing everywhere. Standard library only.
"""
from __future__ import annotations

import ast
import html
import json
import os
import pathlib
import sys
import tempfile
import textwrap
import zipfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import student  # noqa: E402  (the answer key's builder: registry, ast helpers)
import submission_files  # noqa: E402  (the written answers of a submission zip)
from student_docs import lines_of  # noqa: E402

MODEL_SUFFIX = "-model"
MODEL_TAG = "model-answer"


class ReleaseError(Exception):
    """The command cannot run as asked; the message names the argument or file. Nothing was written."""


# ---------------------------------------------------------------------------------------------- checks
def check_edition(tree: pathlib.Path) -> None:
    if not (tree / student.MANIFEST).is_file() or not (tree / "helpers").is_dir():
        raise ReleaseError("TREE %s is not a student edition (it needs the %s manifest that `make student` writes, "
                           "and helpers/)" % (tree, student.MANIFEST))


def resolve(names, reg: dict, root: pathlib.Path) -> list:
    """[("exercise", registry entry) or ("notebook", stem), ...] for the NAMEs, in order, without repeats."""
    exercises = {ex["name"]: ex for ex in reg["exercise"]}
    notebooks = sorted(p.stem for p in (root / "notebooks").glob("*.ipynb"))
    out = []
    for name in dict.fromkeys(names):
        if name in exercises:
            out.append(("exercise", exercises[name]))
            continue
        stem = pathlib.PurePath(name).name.removesuffix(".ipynb")
        found = [s for s in notebooks if s == stem or (stem.isdigit() and s.split("_")[0] == stem.zfill(2))]
        if len(found) != 1:
            raise ReleaseError("unknown NAME %r: neither an exercise of %s nor a notebook of notebooks/ (give its "
                               "number, e.g. 12, or its stem, e.g. %s)" % (name, student.REGISTRY,
                                                                           notebooks[-1] if notebooks else "12_x"))
        out.append(("notebook", found[0]))
    return out


# ---------------------------------------------------------------------------------------------- exercises
def target_state(text, qualname: str, model_dump: str) -> str:
    """stub (the edition's ``raise ExerciseNotImplemented(...)``), model (the answer key's body already), own (the
    student's code), missing (no such file or function) or unparsable (the file is not valid Python)."""
    if text is None:
        return "missing"
    try:
        node = student.find_function(ast.parse(text), qualname)
    except SyntaxError:
        return "unparsable"
    if node is None:
        return "missing"
    stmts = node.body[1:] if student._has_docstring(node) else node.body
    if student.is_stub(stmts):
        return "stub"
    return "model" if "\n".join(ast.dump(s) for s in stmts) == model_dump else "own"


def _with_body(text: str, qualname: str, body: str, scratch: pathlib.Path) -> str:
    """``text`` with the body of ``qualname`` replaced (student.replace_body on a scratch copy, not on TREE)."""
    path = scratch / "module.py"
    path.write_text(text, encoding="utf-8")
    student.replace_body(path, qualname, body)
    return path.read_text(encoding="utf-8")


def whole_function(path: pathlib.Path, qualname: str) -> str:
    """The source of ``qualname`` in ``path``, decorators included, dedented (a method reads as a def)."""
    text = path.read_text(encoding="utf-8")
    node = student.find_function(ast.parse(text), qualname)
    if node is None:
        raise ReleaseError("the answer key's %s has no function %s" % (path, qualname))
    first = min([node.lineno] + [d.lineno for d in node.decorator_list])
    return textwrap.dedent("".join(text.splitlines(keepends=True)[first - 1:node.end_lineno]))


def solution_file(name: str, kept: list, root: pathlib.Path) -> str:
    parts = ["# Exercise %s: the course's model solution, released by the instructor.\n"
             "# Your own code in the workbook was left as it is. Compare it with the function(s) below: each is\n"
             "# for reading, and belongs to the module named above it (it uses that module's imports and names).\n"
             % name]
    for rel, qualname in kept:
        owner = " (a method of class %s)" % qualname.rsplit(".", 1)[0] if "." in qualname else ""
        parts.append("\n\n# %s: %s%s\n%s"
                     % (rel, qualname, owner, whole_function(root / rel, qualname)))
    return "".join(parts)


def _read(path: pathlib.Path, pending: dict):
    if path in pending:
        return pending[path]
    try:
        return path.read_text(encoding="utf-8") if path.is_file() else None
    except (OSError, UnicodeDecodeError):
        return None


def plan_exercise(tree, ex: dict, root, pending: dict, scratch, separate: bool = False) -> list:
    """Put the new texts of the exercise's files into ``pending`` ({path: text}); returns the report lines.
    ``separate``: every target's model solution goes to solutions/, no module of TREE changes."""
    kept, lines = [], []
    out_rel = "solutions/%s.py" % ex["name"]
    for target in ex["targets"]:
        module, qualname = student.split_target(target)
        key_path = student.module_path(root, module)
        rel = key_path.relative_to(root).as_posix()
        key_body = student.function_body_source(key_path, qualname)
        model_dump = student.body_dump(key_path, qualname)
        text = _read(tree / rel, pending)
        state = "separate" if separate else target_state(text, qualname, model_dump)
        where = "%s: %s in %s" % (ex["name"], qualname, rel)
        if state == "stub":
            pending[tree / rel] = _with_body(text, qualname, key_body, scratch)
            lines.append("%s: the stub replaced by the model solution" % where)
        elif state == "model":
            lines.append("%s: already the model solution, unchanged" % where)
        else:
            kept.append((rel, qualname))
            why = {"own": "the student's own code kept", "missing": "not found in TREE",
                   "unparsable": "the file does not parse: left as it is",
                   "separate": "left as it is (--separate)"}[state]
            lines.append("%s: %s; the model solution is in %s" % (where, why, out_rel))
    if kept:
        pending[tree / out_rel] = solution_file(ex["name"], kept, root)
    return lines


# ---------------------------------------------------------------------------------------------- notebooks
def model_cell(answer: dict) -> dict:
    """The answer key's answer cell as a ``model-answer`` cell (keys in nbformat's sorted order)."""
    source = answer.get("source", "")
    text = "".join(source) if isinstance(source, list) else str(source)
    cell_id = str(answer.get("id")) + MODEL_SUFFIX
    meta = {"tags": [MODEL_TAG]}
    if answer.get("cell_type") == "code":
        return {"cell_type": "code", "execution_count": None, "id": cell_id, "metadata": meta, "outputs": [],
                "source": lines_of("# Model answer (the course's).\n" + text)}
    return {"cell_type": "markdown", "id": cell_id, "metadata": meta,
            "source": lines_of("**Model answer.**\n\n" + text)}


def _load_notebook(path: pathlib.Path, text: str) -> dict:
    try:
        nb = json.loads(text)
    except ValueError as err:
        raise ReleaseError("%s is not a readable notebook (%s)" % (path, err)) from None
    if not isinstance(nb, dict) or not isinstance(nb.get("cells"), list):
        raise ReleaseError("%s is not a notebook (no list of cells)" % path)
    return nb


def plan_notebook(tree, stem: str, root, pending: dict, separate: bool = False) -> list:
    """Put the notebook with its model-answer cells into ``pending`` (``separate``: the questions and model answers
    into solutions/<notebook>_answers.md, the notebook unchanged); returns the report lines."""
    key = _load_notebook(root / "notebooks" / (stem + ".ipynb"),
                         (root / "notebooks" / (stem + ".ipynb")).read_text(encoding="utf-8"))
    answers = [c for c in key["cells"] if "answer" in c.get("metadata", {}).get("tags", [])]
    if not answers:
        return ["notebook %s: no written questions, nothing to release" % stem]
    if separate:
        parts = ["# Model answers of notebooks/%s.ipynb\n\nThe course's model answers, released by the instructor; "
                 "your own answers in the notebook are left as they are.\n" % stem]
        for answer in answers:
            source = answer.get("source", "")
            text = "".join(source) if isinstance(source, list) else str(source)
            fence = "```python\n%s\n```" % text.rstrip("\n") if answer.get("cell_type") == "code" else text.rstrip()
            parts.append("\n## %s\n\n%s\n" % (" ".join(str(answer["metadata"].get("question", "")).split()), fence))
        pending[tree / "solutions" / ("%s_answers.md" % stem)] = "".join(parts)
        return ["notebook %s: %d model answers in solutions/%s_answers.md" % (stem, len(answers), stem)]
    path = tree / "notebooks" / (stem + ".ipynb")
    text = _read(path, pending)
    if text is None:
        raise ReleaseError("TREE has no readable notebooks/%s.ipynb" % stem)
    nb = _load_notebook(path, text)
    models = {str(a.get("id")) + MODEL_SUFFIX for a in answers}
    cells = [c for c in nb["cells"] if not (isinstance(c, dict) and c.get("id") in models)]
    ids = [c.get("id") if isinstance(c, dict) else None for c in cells]
    lines = []
    for answer in answers:
        cid = answer.get("id")
        anchor = cid if cid in ids else "%s-question" % cid
        if anchor not in ids:
            lines.append("notebook %s, cell %s: not in TREE's notebook, no model answer inserted" % (stem, cid))
            continue
        at = ids.index(anchor) + 1
        cells.insert(at, model_cell(answer))
        ids.insert(at, cid + MODEL_SUFFIX)
        lines.append("notebook %s, cell %s: model answer inserted after %s" % (
            stem, cid, "the student's answer" if anchor == cid else "the question (the answer cell is gone)"))
    nb["cells"] = cells
    pending[path] = json.dumps(nb, indent=1, ensure_ascii=False) + "\n"
    return lines


# ---------------------------------------------------------------------------------------------- writing
def write_atomic(path: pathlib.Path, text: str) -> None:
    """Write ``text`` to a temporary file next to ``path``, then rename it over ``path`` (mode kept)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    mode = path.stat().st_mode & 0o777 if path.exists() else 0o644
    fd, tmp = tempfile.mkstemp(dir=str(path.parent), prefix="." + path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def release(tree, names, root=ROOT, separate: bool = False) -> list:
    """Release the model solutions of ``names`` into ``tree`` (see the module docstring); returns the report."""
    tree, root = pathlib.Path(tree), pathlib.Path(root)
    check_edition(tree)
    try:
        plan = resolve(names, student.load_registry(root), root)
        pending, lines = {}, []
        with tempfile.TemporaryDirectory(prefix="release-") as scratch:
            for kind, what in plan:
                if kind == "exercise":
                    lines += plan_exercise(tree, what, root, pending, pathlib.Path(scratch), separate)
                else:
                    lines += plan_notebook(tree, what, root, pending, separate)
    except (student.BuildError, OSError, SyntaxError, UnicodeDecodeError) as err:
        raise ReleaseError(str(err)) from None
    for path, text in pending.items():
        if _read(path, {}) != text:
            write_atomic(path, text)
    return lines


# ---------------------------------------------------------------------------------------------- written answers
STYLE = ("body{font-family:system-ui,sans-serif;max-width:60rem;margin:1.5rem auto;padding:0 1rem;line-height:1.4}"
         "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:.3rem .5rem;vertical-align:top}"
         ".text{white-space:pre-wrap;border-left:3px solid #888;padding:.3rem .7rem;background:#f6f6f6}"
         ".missing h2,.unanswered h2{color:#a33}.status{font-size:.8em;font-weight:normal}")
STATUSES = ("answered", "unanswered", "missing")


def page(title: str, body: str) -> str:
    return ('<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n<title>%s</title>\n'
            "<style>%s</style>\n</head>\n<body>\n%s\n</body>\n</html>\n" % (html.escape(title), STYLE, body))


def gather(zips: list, wanted: list) -> dict:
    """{student id: [answer entry per wanted cell]}; a file that is not a readable zip: all missing, with a note."""
    out = {}
    for path in zips:
        note = "not a readable zip file"
        if zipfile.is_zipfile(path):
            try:
                out[path.stem] = submission_files.read_answers(path, wanted)
                continue
            except Exception as err:  # a damaged member must not stop the batch
                note = "the zip cannot be read: %s" % err
        out[path.stem] = [dict(w, answer="", status="missing", note=note) for w in wanted]
    return out


def counts(entries) -> dict:
    statuses = [e["status"] for e in entries]
    return {s: statuses.count(s) for s in STATUSES}


def question_page(i: int, want: dict, answers: dict, names: list) -> str:
    entries = [(sid, answers[sid][i]) for sid in answers]
    n = counts(e for _, e in entries)
    nav = ['<a href="index.html">all questions</a>']
    nav += ['<a href="%s">previous</a>' % names[i - 1]] if i > 0 else []
    nav += ['<a href="%s">next</a>' % names[i + 1]] if i + 1 < len(names) else []
    body = ["<p>%s</p>" % " · ".join(nav), "<h1>Question %d of %d</h1>" % (i + 1, len(names)),
            '<p class="question">%s</p>' % html.escape(want["question"] or "(no question text)"),
            "<p>Notebook <code>%s</code>, cell <code>%s</code></p>" % (html.escape(want["notebook"]),
                                                                       html.escape(str(want["cell"]))),
            "<p><b>%d answered</b>, %d unanswered, %d missing (of %d students)</p>"
            % (n["answered"], n["unanswered"], n["missing"], len(entries))]
    for k, (sid, entry) in enumerate(entries, 1):
        status = entry["status"] + (" (%s)" % entry["note"] if entry.get("note") else "")
        body.append('<section class="%s" id="s%d">\n<h2>%s <span class="status">%s</span></h2>'
                    % (entry["status"], k, html.escape(sid), html.escape(status)))
        if entry["status"] == "answered":
            body.append('<div class="text">%s</div>' % html.escape(entry["answer"]))
        body.append("</section>")
    return page("Question %d: %s" % (i + 1, want["notebook"]), "\n".join(body))


def index_page(wanted: list, answers: dict, names: list) -> str:
    rows = []
    for i, (want, name) in enumerate(zip(wanted, names)):
        n = counts(answers[sid][i] for sid in answers)
        rows.append('<tr><td><a href="%s">%d</a></td><td>%s</td><td><code>%s</code></td><td>%d</td><td>%d</td>'
                    "<td>%d</td></tr>" % (name, i + 1, html.escape(want["question"]), html.escape(want["notebook"]),
                                          n["answered"], n["unanswered"], n["missing"]))
    bad = ["<li>%s: %s</li>" % (html.escape(sid), html.escape(a[0]["note"])) for sid, a in answers.items()
           if a and a[0].get("note")]
    body = ["<h1>Written answers</h1>", "<p>%d questions, %d students: %s.</p>" % (
        len(wanted), len(answers), html.escape(", ".join(answers)))]
    body += ["<p>Unreadable submissions (missing everywhere):</p>", "<ul>%s</ul>" % "".join(bad)] if bad else []
    body += ["<table>", "<tr><th>#</th><th>question</th><th>notebook</th><th>answered</th><th>unanswered</th>"
             "<th>missing</th></tr>"] + rows + ["</table>"]
    return page("Written answers", "\n".join(body))


def answers_html(submissions, out=None, root=ROOT) -> pathlib.Path:
    """Write the answer pages of every zip of ``submissions`` into ``out``; returns ``out``."""
    submissions = pathlib.Path(submissions)
    if not submissions.is_dir():
        raise ReleaseError("SUBMISSIONS_DIR %s is not a folder" % submissions)
    zips = sorted(p for p in submissions.glob("*.zip") if p.is_file())
    if not zips:
        raise ReleaseError("SUBMISSIONS_DIR %s holds no *.zip submission" % submissions)
    out = pathlib.Path(out) if out else submissions / "answers-html"
    wanted = submission_files.answer_cells(root)
    answers = gather(zips, wanted)
    width = max(2, len(str(len(wanted))))
    names = ["q%0*d.html" % (width, i + 1) for i in range(len(wanted))]
    for i, want in enumerate(wanted):
        write_atomic(out / names[i], question_page(i, want, answers, names))
    write_atomic(out / "index.html", index_page(wanted, answers, names))
    return out


# ---------------------------------------------------------------------------------------------- command line
def main(argv=None, root=ROOT) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if {"-h", "--help"} & set(argv):
        print(__doc__)
        return 0
    separate = "--separate" in argv
    argv = [a for a in argv if a != "--separate"]
    try:
        if argv[:1] == ["solutions"] and len(argv) >= 3:
            print("\n".join(release(argv[1], argv[2:], root, separate)))
        elif argv[:1] == ["answers"] and (len(argv) == 2 or (len(argv) == 4 and argv[2] == "--out")):
            out = answers_html(argv[1], argv[3] if len(argv) == 4 else None, root)
            print("written answers: %s" % (out / "index.html"))
        else:
            print(__doc__, file=sys.stderr)
            return 2
    except ReleaseError as err:
        print("error: %s" % err, file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
