"""Releasing model solutions into a student's tree and gathering written answers (tools/release.py).

The trees are small and synthetic: the answer key's module files of two exercises, stubbed as the edition stubs
them, next to a fake build manifest; the notebook and the answers tests use a fake answer key holding one tiny
notebook with a Markdown and a code answer cell."""
import io
import json
import pathlib
import re
import subprocess
import sys
import zipfile

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

import release  # noqa: E402
import student  # noqa: E402
import student_docs  # noqa: E402

pytestmark = pytest.mark.cpu_independent  # text processing of source files and notebooks only

EDGES = "helpers/graph/edges2d.py"
SLAM = "helpers/drivebot/slam_system.py"
STUBS = {("cw_q1c_compass_fix", EDGES, "EdgeHeadingPrior.evaluate"),
         ("cw_q1d_gps", EDGES, "EdgePositionPrior.evaluate"),
         ("cw_q1d_gps", SLAM, "DriveBotSLAMSystem._handle_gps")}
KEY_ANSWER = "The gate is **χ²** with <b>2</b> dof."
NOTEBOOK = "notebooks/99_tiny.ipynb"


def snapshot(tree: pathlib.Path) -> dict:
    return {p.relative_to(tree).as_posix(): p.read_bytes() for p in sorted(tree.rglob("*")) if p.is_file()}


@pytest.fixture
def tree(tmp_path):
    """A student edition reduced to the two module files of cw_q1c_compass_fix and cw_q1d_gps, all stubbed."""
    dest = tmp_path / "student"
    for rel in (EDGES, SLAM):
        (dest / rel).parent.mkdir(parents=True, exist_ok=True)
        (dest / rel).write_text((ROOT / rel).read_text(encoding="utf-8"), encoding="utf-8")
    for name, rel, qualname in STUBS:
        student.replace_body(dest / rel, qualname, student.stub_body(name))
    (dest / student.MANIFEST).write_text("%s\n%s\n" % (EDGES, SLAM), encoding="utf-8")
    return dest


def key_notebook() -> dict:
    cells = [{"cell_type": "markdown", "id": "intro", "metadata": {}, "source": ["# Tiny\n"]},
             {"cell_type": "code", "execution_count": 1, "id": "setup", "metadata": {}, "outputs": [],
              "source": ["import math"]},
             {"cell_type": "markdown", "id": "q1", "metadata": {"question": "Why the gate?", "tags": ["answer"]},
              "source": student_docs.lines_of(KEY_ANSWER)},
             {"cell_type": "code", "execution_count": 3, "id": "q2",
              "metadata": {"question": "Count the <edges>.", "tags": ["answer"]},
              "outputs": [{"name": "stdout", "output_type": "stream", "text": ["7\n"]}], "source": ["print(7)"]}]
    return {"cells": cells, "metadata": {}, "nbformat": 4, "nbformat_minor": 5}


@pytest.fixture
def key(tmp_path):
    """A fake answer key: an empty registry and the tiny notebook."""
    root = tmp_path / "key"
    (root / "tools").mkdir(parents=True)
    (root / "tools" / "exercises.toml").write_text("exercise = []\n", encoding="utf-8")
    (root / "notebooks").mkdir()
    (root / NOTEBOOK).write_text(json.dumps(key_notebook(), indent=1), encoding="utf-8")
    return root


def student_notebook(answer: str) -> dict:
    """The tiny notebook as the edition gives it, with ``answer`` written into the Markdown answer cell."""
    nb = student_docs.student_notebook(key_notebook(), [], set())
    cell = next(c for c in nb["cells"] if c["id"] == "q1")
    cell["source"] = student_docs.lines_of(answer)
    return nb


# ---------------------------------------------------------------------------------------------- exercises
def test_a_stub_gets_the_model_body_in_place(tree):
    lines = release.release(tree, ["cw_q1c_compass_fix"])
    path = tree / EDGES
    assert student.body_dump(path, "EdgeHeadingPrior.evaluate") == \
        student.body_dump(ROOT / EDGES, "EdgeHeadingPrior.evaluate")
    assert release.target_state(path.read_text(encoding="utf-8"), "EdgePositionPrior.evaluate", "") == "stub"
    assert lines == ["cw_q1c_compass_fix: EdgeHeadingPrior.evaluate in %s: the stub replaced by the model "
                     "solution" % EDGES]
    assert not (tree / "solutions").exists()


def test_the_students_own_work_is_kept_and_the_solution_goes_to_its_own_file(tree):
    student.replace_body(tree / EDGES, "EdgePositionPrior.evaluate", "return 'mine'  # my own work")
    lines = release.release(tree, ["cw_q1d_gps"])
    assert "return 'mine'  # my own work" in (tree / EDGES).read_text(encoding="utf-8")
    assert student.body_dump(tree / SLAM, "DriveBotSLAMSystem._handle_gps") == \
        student.body_dump(ROOT / SLAM, "DriveBotSLAMSystem._handle_gps")
    solution = (tree / "solutions" / "cw_q1d_gps.py").read_text(encoding="utf-8")
    release.ast.parse(solution)
    assert "model solution" in solution and "# %s: EdgePositionPrior.evaluate" % EDGES in solution
    assert release.whole_function(ROOT / EDGES, "EdgePositionPrior.evaluate") in solution
    assert "_handle_gps" not in solution
    assert any("own code kept" in ln and "solutions/cw_q1d_gps.py" in ln for ln in lines)
    before = snapshot(tree)
    again = release.release(tree, ["cw_q1d_gps"])
    assert snapshot(tree) == before
    assert any("_handle_gps" in ln and "already the model solution" in ln for ln in again)


# ---------------------------------------------------------------------------------------------- notebooks
def test_model_answers_go_after_the_students_cells_once(tree, key):
    path = tree / NOTEBOOK
    path.parent.mkdir()
    nb = student_notebook("My answer: <because>.")
    path.write_text(json.dumps(nb, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    assert release.main(["solutions", str(tree), "99"], root=key) == 0
    text = path.read_text(encoding="utf-8")
    out = json.loads(text)
    assert text == json.dumps(out, indent=1, ensure_ascii=False) + "\n"
    assert [c["id"] for c in out["cells"]] == ["intro", "setup", "q1-question", "q1", "q1-model", "q2-question",
                                               "q2", "q2-model"]
    by_id = {c["id"]: c for c in out["cells"]}
    assert by_id["q1"] == next(c for c in nb["cells"] if c["id"] == "q1")
    assert by_id["q1-model"]["cell_type"] == "markdown"
    assert by_id["q1-model"]["metadata"]["tags"] == ["model-answer"]
    assert "".join(by_id["q1-model"]["source"]) == "**Model answer.**\n\n" + KEY_ANSWER
    assert by_id["q2-model"]["cell_type"] == "code" and by_id["q2-model"]["outputs"] == []
    assert "".join(by_id["q2-model"]["source"]).endswith("print(7)")
    assert release.main(["solutions", str(tree), "99_tiny"], root=key) == 0
    assert path.read_text(encoding="utf-8") == text


def test_separate_changes_only_solutions_so_a_git_pull_never_conflicts(tree, key):
    """--separate (the published edition): the stub and the notebook stay as they are; the model functions and
    the model answers are new files under solutions/."""
    path = tree / NOTEBOOK
    path.parent.mkdir()
    path.write_text(json.dumps(student_notebook(""), indent=1) + "\n", encoding="utf-8")
    before = snapshot(tree)
    assert release.main(["solutions", str(tree), "cw_q1c_compass_fix", "--separate"]) == 0
    assert release.main(["solutions", str(tree), "99", "--separate"], root=key) == 0
    after = snapshot(tree)
    assert {k: v for k, v in after.items() if not k.startswith("solutions/")} == before
    solution = (tree / "solutions" / "cw_q1c_compass_fix.py").read_text(encoding="utf-8")
    assert release.whole_function(ROOT / EDGES, "EdgeHeadingPrior.evaluate") in solution
    answers = (tree / "solutions" / "99_tiny_answers.md").read_text(encoding="utf-8")
    assert KEY_ANSWER in answers and "```python" in answers and "print(7)" in answers


# ---------------------------------------------------------------------------------------------- errors
def test_unknown_name_or_not_an_edition_writes_nothing(tree, tmp_path, capsys):
    before = snapshot(tree)
    assert release.main(["solutions", str(tree), "cw_q1c_compass_fix", "no_such_exercise"]) == 2
    assert "unknown NAME 'no_such_exercise'" in capsys.readouterr().err
    assert release.main(["solutions", str(tree), "cw_q1c_compass_fix", "12"]) == 2   # no notebooks/ in TREE
    assert "notebooks/12_q1_c_compass.ipynb" in capsys.readouterr().err
    assert snapshot(tree) == before
    (tree / student.MANIFEST).unlink()
    before = snapshot(tree)
    run = subprocess.run([sys.executable, str(ROOT / "tools" / "release.py"), "solutions", str(tree),
                          "cw_q1c_compass_fix"], capture_output=True, text=True, check=False)
    assert run.returncode == 2 and "is not a student edition" in run.stderr
    assert snapshot(tree) == before


# ---------------------------------------------------------------------------------------------- answers
def make_zip(path: pathlib.Path, files: dict) -> None:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, text in files.items():
            zf.writestr(name, text)


def damaged_zip(path: pathlib.Path) -> None:
    """A zip whose notebook member's compressed bytes are corrupt (reading it raises a zlib error)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(NOTEBOOK, json.dumps(student_notebook("x " * 4000)))
    data = bytearray(buf.getvalue())
    for k in range(60, 90):
        data[k] ^= 0xFF
    path.write_bytes(bytes(data))


def test_answers_pages_per_question(key, tmp_path):
    subs = tmp_path / "subs"
    subs.mkdir()
    answer = "<script>alert(1)</script> & so\n    indented"
    make_zip(subs / "alice.zip", {NOTEBOOK: json.dumps(student_notebook(answer))})
    make_zip(subs / "bob.zip", {EDGES: "x = 1\n"})                    # no notebook
    (subs / "carol.zip").write_bytes(b"this is not a zip")
    damaged_zip(subs / "dave.zip")
    assert release.main(["answers", str(subs)], root=key) == 0
    out = subs / "answers-html"
    assert sorted(p.name for p in out.iterdir()) == ["index.html", "q01.html", "q02.html"]
    q1 = (out / "q01.html").read_text(encoding="utf-8")
    assert "&lt;script&gt;alert(1)&lt;/script&gt; &amp; so\n    indented" in q1 and "<script" not in q1
    assert "white-space:pre-wrap" in q1 and '<meta charset="utf-8">' in q1
    assert "<b>1 answered</b>, 0 unanswered, 3 missing (of 4 students)" in q1
    assert [q1.index("<h2>%s " % s) for s in ("alice", "bob", "carol", "dave")] == \
        sorted(q1.index("<h2>%s " % s) for s in ("alice", "bob", "carol", "dave"))
    assert "missing (not a readable zip file)" in q1 and '<h2>dave <span class="status">missing</span>' in q1
    q2 = (out / "q02.html").read_text(encoding="utf-8")
    assert "Count the &lt;edges&gt;." in q2 and "<b>0 answered</b>, 1 unanswered, 3 missing" in q2
    index = (out / "index.html").read_text(encoding="utf-8")
    assert re.findall(r'href="([^"]+)"', index) == ["q01.html", "q02.html"]
    assert "<td>1</td><td>0</td><td>3</td>" in index and "<td>0</td><td>1</td><td>3</td>" in index
    for page in (q1, q2, index):
        assert not re.search(r"(src|href)=\"(https?:)?//|<link|@import|url\(", page)


def test_answers_needs_a_folder_of_zips(tmp_path, capsys):
    assert release.main(["answers", str(tmp_path)]) == 2
    assert "holds no *.zip" in capsys.readouterr().err
    assert not (tmp_path / "answers-html").exists()
