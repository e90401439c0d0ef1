"""The student-edition tooling (tools/student.py, tools/student_docs.py, tools/grade.py, helpers/exercises.py).

Unit tests on a tiny synthetic tree and registry, plus one build of the real registry per session into a
temporary directory (about a second: it copies files and edits ASTs, it runs no test) and a few calls of the fast
paths inside that tree (subprocesses, a few seconds). The end-to-end grading of both trees is the CI check
``tools/student_check.py`` (``CI=true make test``)."""
import ast
import json
import os
import pathlib
import shutil
import subprocess
import sys
import textwrap

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

import grade  # noqa: E402
import student  # noqa: E402
import student_docs  # noqa: E402

from helpers import exercises  # noqa: E402

MODULE = '''"""A module."""
from __future__ import annotations

import numpy as np


def helper(x):
    return x + 1


def area(width, height):
    """Width times height."""
    # the answer
    product_of_the_sides = np.multiply(width, height)
    return product_of_the_sides


class Shape:
    """A shape."""

    @staticmethod
    def perimeter(width, height):
        double_the_sum_of_sides = 2 * (width + height)
        return double_the_sum_of_sides
'''

REGISTRY = '''
[edition]
keep_outputs = [{ notebook = "notebooks/01_demo.ipynb", cells = ["keep-me"] }]
remove = ["secret"]

[[exercise]]
name = "ex_area"
source = "Sheet 1, task a"
task = "Compute the area."
targets = ["pkg.shapes:area"]
notebooks = ["01_demo"]

[[exercise]]
name = "ex_perimeter"
source = "Sheet 1, task b"
task = "Compute the perimeter."
targets = ["pkg.shapes:Shape.perimeter"]
'''


def _notebook(*cells):
    return {"nbformat": 4, "nbformat_minor": 5, "metadata": {}, "cells": list(cells)}


def _code(cell_id, source, text):
    return {"cell_type": "code", "id": cell_id, "metadata": {}, "execution_count": 1, "source": [source],
            "outputs": [{"output_type": "stream", "name": "stdout", "text": [text]}]}


@pytest.fixture
def tree(tmp_path):
    root = tmp_path / "key"
    (root / "pkg").mkdir(parents=True)
    (root / "pkg" / "__init__.py").write_text("", encoding="utf-8")
    (root / "pkg" / "shapes.py").write_text(MODULE, encoding="utf-8")
    (root / "tools").mkdir()
    (root / "tools" / "exercises.toml").write_text(REGISTRY, encoding="utf-8")
    (root / "secret").mkdir()
    (root / "secret" / "answers.txt").write_text("42", encoding="utf-8")
    (root / "README.md").write_text("# Demo\n\n## Use\n\nRun it.\n\n## Benchmarks\n\nTimes.\n", encoding="utf-8")
    (root / "tools" / "student_readme.md").write_text("# Student edition\n\n{n} exercises.\n", encoding="utf-8")
    (root / "tests" / "exercises" / "fixtures").mkdir(parents=True)
    for name in ("ex_area", "ex_perimeter"):
        (root / "tests" / "exercises" / ("test_%s.py" % name)).write_text("def test_x():\n    pass\n", encoding="utf-8")
    (root / "tests" / "exercises" / "test_ex_area_hidden.py").write_text("# expected 6\n", encoding="utf-8")
    (root / "tests" / "exercises" / "fixtures" / "ex_area_hidden.npz").write_bytes(b"")
    (root / "tests" / "exercises" / "fixtures" / "ex_area.npz").write_bytes(b"")
    (root / "tests" / "test_key.py").write_text("def test_key():\n    pass\n", encoding="utf-8")
    (root / "notebooks").mkdir()
    answer = {"cell_type": "markdown", "id": "why", "metadata": {"tags": ["answer"], "question": "Why is it 6?"},
              "source": ["Because the width times the height of this rectangle is six square units."]}
    check = _code("claims", "assert x == 1\n", "")
    check["metadata"] = {"tags": ["check"], "jupyter": {"source_hidden": True}}
    nb = _notebook({"cell_type": "markdown", "id": "title", "metadata": {}, "source": ["# 01 demo"]},
                   _code("first", "x = 1\n", "1\n"), check, _code("keep-me", "print(2)\n", "2\n"),
                   _code("strip-me", "print(3)\n", "3\n"), answer)
    (root / "notebooks" / "01_demo.ipynb").write_text(json.dumps(nb), encoding="utf-8")
    return root


def test_build_stubs_targets_and_keeps_signature_docstring_and_decorators(tree, tmp_path):
    dest = student.build(tmp_path / "student", root=tree, quiet=True)
    text = (dest / "pkg" / "shapes.py").read_text(encoding="utf-8")
    assert "product_of_the_sides" not in text and "double_the_sum_of_sides" not in text
    assert "# the answer" not in text
    assert '"""Width times height."""' in text and "@staticmethod" in text
    assert "def helper(x):\n    return x + 1" in text
    assert student.IMPORT_LINE in text and text.index(student.IMPORT_LINE) > text.index("from __future__")
    ast.parse(text)
    for qualname, name in (("area", "ex_area"), ("Shape.perimeter", "ex_perimeter")):
        assert student.body_dump(dest / "pkg" / "shapes.py", qualname) == ast.dump(
            ast.parse(student.stub_body(name)).body[0])
    assert not (dest / "secret").exists()
    assert student.self_check(dest, tree, student.load_registry(tree)) == []


def test_stub_raises_the_exercise_error(tree, tmp_path):
    dest = student.build(tmp_path / "student", root=tree, quiet=True)
    namespace = {"__name__": "shapes_student"}
    exec(compile((dest / "pkg" / "shapes.py").read_text(encoding="utf-8"), "shapes.py", "exec"), namespace)
    with pytest.raises(exercises.ExerciseNotImplemented, match="ex_area") as info:
        namespace["area"](2, 3)
    assert isinstance(info.value, NotImplementedError)
    assert info.value.exercise == "ex_area" and info.value.where == "EXERCISES.md, section ex_area"
    assert namespace["helper"](1) == 2


def test_self_check_finds_a_body_left_in_place_and_a_solution_line_elsewhere(tree, tmp_path):
    dest = student.build(tmp_path / "student", root=tree, quiet=True)
    reg = student.load_registry(tree)
    student.copy_solution(dest, "ex_area", root=tree)
    nb_path = dest / "notebooks" / "01_demo.ipynb"
    nb = json.loads(nb_path.read_text(encoding="utf-8"))
    nb["cells"].append(_code("leak", "pass\n", "double_the_sum_of_sides = 2 * (width + height)\n"))
    nb_path.write_text(json.dumps(nb), encoding="utf-8")
    problems = student.self_check(dest, tree, reg)
    assert any("ex_area: the body of pkg.shapes:area is not the stub" in p for p in problems)
    assert any(p.startswith("notebooks/01_demo.ipynb") and "ex_perimeter" in p for p in problems)
    assert any(p.startswith("pkg/shapes.py") and "product_of_the_sides" in p for p in problems)


def test_copy_solution_restores_the_answer_key_body(tree, tmp_path):
    dest = student.build(tmp_path / "student", root=tree, quiet=True)
    student.copy_solution(dest, "ex_perimeter", root=tree)
    assert student.body_dump(dest / "pkg" / "shapes.py", "Shape.perimeter") == \
        student.body_dump(tree / "pkg" / "shapes.py", "Shape.perimeter")
    with pytest.raises(student.BuildError, match="no exercise"):
        student.copy_solution(dest, "nope", root=tree)


def test_registry_errors_name_the_problem(tree):
    path = tree / "tools" / "exercises.toml"
    (tree / "tests" / "exercises" / "test_ex_perimeter.py").unlink()
    with pytest.raises(student.BuildError, match="no tests/exercises/test_ex_perimeter.py"):
        student.load_registry(tree)
    (tree / "tests" / "exercises" / "test_ex_perimeter.py").write_text("", encoding="utf-8")
    path.write_text(REGISTRY.replace('"pkg.shapes:area"', '"pkg.shapes:volume"'), encoding="utf-8")
    with pytest.raises(student.BuildError, match="no function volume"):
        student.build(tree.parent / "student", root=tree, quiet=True)


def test_notebooks_readme_and_exercises_document(tree, tmp_path):
    dest = student.build(tmp_path / "student", root=tree, quiet=True)
    nb = json.loads((dest / "notebooks" / "01_demo.ipynb").read_text(encoding="utf-8"))
    ids = [c["id"] for c in nb["cells"]]
    assert ids == ["title", student_docs.EXERCISE_CELL_ID, "first", "keep-me", "strip-me", "why-question", "why"]
    cells = {c["id"]: c for c in nb["cells"]}
    assert "ex_area" in "".join(cells[student_docs.EXERCISE_CELL_ID]["source"])
    assert "".join(cells["first"]["source"]).startswith(student_docs.NOTEBOOK_IMPORT + "\n")
    assert cells["keep-me"]["outputs"] and cells["keep-me"]["execution_count"] == 1
    assert cells["strip-me"]["outputs"] == [] and cells["strip-me"]["execution_count"] is None
    assert "".join(cells["why-question"]["source"]) == "**Question.** Why is it 6?"
    assert cells["why"]["metadata"]["tags"] == ["student-answer"] and "six square" not in json.dumps(nb)
    assert (dest / "README.md").read_text(encoding="utf-8") == "# Student edition\n\n2 exercises.\n"
    doc = (dest / "EXERCISES.md").read_text(encoding="utf-8")
    assert "## ex_perimeter" in doc and "`Shape.perimeter` in `pkg/shapes.py`" in doc
    assert "tests/exercises/test_ex_perimeter.py" in doc
    shipped = sorted(p.relative_to(dest).as_posix() for p in (dest / "tests").rglob("*") if p.is_file())
    assert shipped == ["tests/exercises/fixtures/ex_area.npz", "tests/exercises/test_ex_area.py",
                       "tests/exercises/test_ex_perimeter.py"]


def test_self_check_finds_answer_lines_tagged_cells_and_hidden_files(tree, tmp_path):
    dest = student.build(tmp_path / "student", root=tree, quiet=True)
    (dest / "NOTES.md").write_text("Because the width times the height of this rectangle is six square units.\n",
                                   encoding="utf-8")
    (dest / "tests" / "exercises" / "test_ex_area_hidden.py").write_text("", encoding="utf-8")
    nb_path = dest / "notebooks" / "01_demo.ipynb"
    nb = json.loads(nb_path.read_text(encoding="utf-8"))
    nb["cells"][2]["metadata"]["tags"] = ["check"]
    nb_path.write_text(json.dumps(nb), encoding="utf-8")
    problems = student.self_check(dest, tree, student.load_registry(tree))
    assert any(p.startswith("NOTES.md:1 shows a line of an answer cell") for p in problems)
    assert any(p.startswith("tests/exercises/test_ex_area_hidden.py") for p in problems)
    assert any("tagged ['check']" in p for p in problems)


class _Report:
    def __init__(self, text, message):
        self.longreprtext, self.longrepr = text, type("L", (), {"reprcrash": type("C", (), {"message": message})})


def test_grader_report_shows_the_check_and_the_hint(capsys):
    exes = [{"name": "a", "targets": [], "hints": {"test_y": "look at the sign"}}, {"name": "b", "targets": []},
            {"name": "c", "targets": []}]
    col = grade.Collector()
    col.outcome = {"tests/exercises/test_a.py::test_x": "passed", "tests/exercises/test_a_hidden.py::test_y": "failed",
                   "tests/exercises/test_b.py::test_z[1]": "failed"}
    col.failure = {"tests/exercises/test_a_hidden.py::test_y": "check: the sign\n  expected: 1\n  actual:   -1",
                   "tests/exercises/test_b.py::test_z[1]": "not written yet: exercise b raises ExerciseNotImplemented"}
    col.doc = {"tests/exercises/test_a_hidden.py::test_y": "The sign is kept"}
    assert grade.report(col, exes) == []
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:2] == ["a", "FAILED"] and out[1].strip() == "✗ [hidden] The sign is kept (test_y)"
    assert out[2].strip() == "check: the sign" and out[5].strip() == "hint: look at the sign"
    assert out[-3].split()[:4] == ["b", "not", "written", "yet:"]
    assert out[-2].split()[:2] == ["c", "FAILED"] and "no test" in out[-2]
    assert out[-1] == "exercises: 0 passed, 3 failed"
    assert grade.exercise_of("tests/exercises/test_cw_q1b_prediction_hidden.py::t") == "cw_q1b_prediction"


def test_failure_text_keeps_our_message_the_raise_site_and_the_falsifying_example():
    ours = _Report("E   AssertionError: check: x\n  expected: 1", "AssertionError: check: x\n  expected: 1")
    assert grade._failure_text(ours) == "check: x\n  expected: 1"
    text = ("    def f(x):\n>       return x[3]\nE       IndexError: index 3 is out of bounds\n\n"
            "helpers/pkg/mod.py:12: IndexError\nFalsifying example: test_f(\n    x=[0],\n)\n")
    got = grade._failure_text(_Report(text, "IndexError: index 3 is out of bounds"))
    assert got.splitlines()[:2] == ["IndexError: index 3 is out of bounds", "  raised at helpers/pkg/mod.py:12"]
    assert "Falsifying example: test_f(" in got and "x=[0]," in got
    stub = _Report("ExerciseNotImplemented: exercise l09_jcbb is not implemented yet", "E")
    assert grade._failure_text(stub).startswith("not written yet: exercise l09_jcbb")


def test_isolate_swaps_the_code_of_the_other_exercises_targets():
    code = ("import json, sys\nsys.path.insert(0, 'tools')\nimport grade\n"
            "n = grade.isolate('l09_jcbb', grade.load()['exercise'])\n"
            "from helpers.association.nearest_neighbour import nearest_neighbour\n"
            "from helpers.exercises import ExerciseNotImplemented\n"
            "try:\n    nearest_neighbour(None, None)\nexcept ExerciseNotImplemented as err:\n"
            "    print(json.dumps([n, err.exercise]))\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=str(ROOT), capture_output=True, text=True, timeout=300)
    n, name = json.loads(out.stdout.strip().splitlines()[-1])
    assert name == "l09_euclidean_nn" and n == sum(len(ex["targets"]) for ex in grade.load()["exercise"]) - 1


def test_notebook_handler_prints_one_short_message(capsys):
    class Shell:
        def set_custom_exc(self, exc_tuple, handler):
            self.exc_tuple, self.handler = exc_tuple, handler

    shell = Shell()
    assert exercises.install_notebook_handler(shell)
    assert shell.exc_tuple == (exercises.ExerciseNotImplemented,)
    err = exercises.ExerciseNotImplemented("cw_q1b_prediction", "EXERCISES.md, section cw_q1b_prediction")
    assert shell.handler(shell, type(err), err, None) == []
    printed = capsys.readouterr().err.strip().splitlines()
    assert len(printed) == 1 and "cw_q1b_prediction" in printed[0] and "make grade EX=cw_q1b_prediction" in printed[0]
    shown = []
    shell._showtraceback = lambda etype, value, stb: shown.append(stb)   # IPython: the cell's error, one line
    assert shell.handler(shell, type(err), err, None) == []
    assert len(shown) == 1 and len(shown[0]) == 1 and shown[0][0] == printed[0]


@pytest.fixture(scope="session")
def real_edition(tmp_path_factory):
    """The student edition of the real registry, built once per session (tests that change it copy it)."""
    return student.build(tmp_path_factory.mktemp("edition") / "student", quiet=True)   # raises if the self-check fails


@pytest.mark.cpu_independent  # the builder's text and the stubs' exceptions: no float reaches the result
def test_the_real_registry_builds_a_clean_student_edition(real_edition):
    reg = student.load_registry()
    assert len(reg["exercise"]) >= 14
    dest = real_edition
    for ex in reg["exercise"]:
        for target in ex["targets"]:
            module, qualname = student.split_target(target)
            assert student.body_dump(student.module_path(dest, module), qualname) != \
                student.body_dump(student.module_path(ROOT, module), qualname), target
        assert (dest / "tests" / "exercises" / ("test_%s.py" % ex["name"])).exists(), ex["name"]
        assert not (dest / "tests" / "exercises" / ("test_%s_hidden.py" % ex["name"])).exists(), ex["name"]
    assert (dest / "EXERCISES.md").exists() and (dest / "tools" / "grade.py").exists()
    assert not (dest / "tools" / "student.py").exists()
    text = (dest / "helpers" / "drivebot" / "edges.py").read_text(encoding="utf-8")
    assert "evaluate_reference" not in text      # one kinematics model: the student's evaluate is what runs


# ------------------------------------------------------------------------- rewrites and the student's code
def _body_of(text):
    """The AST dump of a rewrite body as the builder writes it (indented into a function: multi-line strings in
    it gain the indentation)."""
    source = "def f():\n" + textwrap.indent(textwrap.dedent(text).strip("\n") + "\n", "    ")
    return "\n".join(ast.dump(s) for s in ast.parse(source).body[0].body)


@pytest.mark.cpu_independent  # the builder's text and the stubs' exceptions: no float reaches the result
def test_every_fast_path_is_the_rewrite_in_the_student_edition(real_edition):
    reg = student.load_registry()
    rewrites = reg["edition"]["rewrite"]
    for entry in rewrites:
        module, qualname = student.split_target(entry["target"])
        got = student.body_dump(student.module_path(real_edition, module), qualname)
        assert got == _body_of(entry["body"]), entry["target"]
        assert got != student.body_dump(student.module_path(ROOT, module), qualname), entry["target"]
    for rel in reg["edition"]["remove"]:
        assert not (real_edition / rel).exists(), rel
    for entry in reg["edition"].get("kept", []):
        assert entry["exercise"] in {ex["name"] for ex in reg["exercise"]} and entry["why"], entry["target"]


@pytest.mark.cpu_independent  # the builder's text and the stubs' exceptions: no float reaches the result
def test_no_line_of_a_fast_path_remains_in_the_student_edition(real_edition):
    reg = student.load_registry()
    assert student.self_check(real_edition, ROOT, reg) == []


def _run_in(tree, code):
    """Run ``code`` with the student tree's helpers (a fresh interpreter: this one imported the answer key's)."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-W", "error", "-c", textwrap.dedent(code)], cwd=str(tree), env=env,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


STOPS = """
    import json
    import numpy as np
    from helpers.association.compatibility import lab_test_fixture
    from helpers.association.jcbb import jcbb
    from helpers.association.scenarios import range_bearing_scenario
    from helpers.association.snn import snn
    from helpers.exercises import ExerciseNotImplemented
    fx, sc = lab_test_fixture(), range_bearing_scenario(seed=3, n_landmarks=40, n_visible=8, n_clutter=3)
    calls = {"jcbb": lambda: jcbb(sc.density, sc.Y), "jcbb_trace": lambda: jcbb(sc.density, sc.Y, trace=True),
             "snn": lambda: snn(fx["density_3"], fx["Y13"], fx["sU"])}
    out = {}
    for name, call in calls.items():
        try:
            call()
            out[name] = "returned"
        except ExerciseNotImplemented as err:
            out[name] = err.exercise
    try:
        jcbb(sc.density, sc.Y, max_nodes=0)
    except ValueError as err:
        out["bad_input"] = str(err)
    print(json.dumps(out))
"""


@pytest.mark.cpu_independent  # the builder's text and the stubs' exceptions: no float reaches the result
def test_fast_paths_stop_at_the_exercise_in_a_fresh_student_edition(real_edition):
    out = _run_in(real_edition, STOPS)
    assert out["jcbb"] == out["jcbb_trace"] == "l09_jcbb"
    assert out["snn"] == "lab8_2c_joint_compatibility"
    assert out["bad_input"].startswith("max_nodes")                # checked before the student's code runs


RUNS = """
    import json
    import numpy as np
    from helpers.association.compatibility import lab_test_fixture
    from helpers.association.jcbb import TRACE_BEST, TRACE_EXPANDED, jcbb
    from helpers.association.scenarios import range_bearing_scenario
    from helpers.association.snn import snn
    from helpers.exercises import ExerciseNotImplemented
    fx, sc = lab_test_fixture(), range_bearing_scenario(seed=3, n_landmarks=40, n_visible=8, n_clutter=3)


    def surprisal_nn():
        idx, s = snn(fx["density_3"], fx["Y13"], fx["sU"])
        far, s_far = snn(fx["density_3"], fx["Y13"] + 1e4, fx["sU"])       # no feature near any landmark
        return [idx.tolist(), s, far.tolist(), s_far]


    def search():
        res = jcbb(sc.density, sc.Y, trace=True)
        tr = res.stats["trace"]
        return {"idx": res.idx.tolist(), "algorithm": res.algorithm, "nodes": res.stats["nodes"],
                "expanded": int(np.isin(tr.status, [TRACE_EXPANDED, TRACE_BEST]).sum()),
                "parents_first": bool(np.all(tr.parent[1:] < np.arange(1, tr.parent.size))),
                "root": [int(tr.parent[0]), int(tr.level[0])]}


    out = {}
    for name, call in (("snn", surprisal_nn), ("jcbb", search)):
        try:
            out[name] = call()
        except ExerciseNotImplemented as err:
            out[name] = err.exercise
    print(json.dumps(out))
"""


def test_copied_solutions_run_in_the_association_algorithms(real_edition, tmp_path):
    """The "runs on the student's code" property: with the answer key's body of an exercise copied into the
    student tree, the algorithms built on it give the answer key's results, and only those."""
    from helpers.association.compatibility import lab_test_fixture
    from helpers.association.jcbb import jcbb
    from helpers.association.scenarios import range_bearing_scenario
    from helpers.association.snn import snn

    fx, sc = lab_test_fixture(), range_bearing_scenario(seed=3, n_landmarks=40, n_visible=8, n_clutter=3)
    tree = tmp_path / "student"
    shutil.copytree(real_edition, tree)
    out = _run_in(tree, RUNS)
    assert out["snn"] == "lab8_2c_joint_compatibility" and out["jcbb"] == "l09_jcbb"
    for name in ("lab8_2c_joint_compatibility", "l09_jcbb"):
        student.copy_solution(tree, name)
    out = _run_in(tree, RUNS)
    idx, s = snn(fx["density_3"], fx["Y13"], fx["sU"])
    far, s_far = snn(fx["density_3"], fx["Y13"] + 1e4, fx["sU"])
    # the choices are far from ties (best and second Δs differ by ≥ 0.36, the null by ≥ 2.8) and both sides end
    # with joint_compatibility of the same association, so the surprisals agree to round-off
    assert out["snn"][0] == idx.tolist() and out["snn"][1] == pytest.approx(s, rel=1e-12)
    assert out["snn"][2] == far.tolist() == [-1, -1, -1] and out["snn"][3] == pytest.approx(s_far, rel=1e-12)
    search = out["jcbb"]
    assert search["idx"] == jcbb(sc.density, sc.Y).idx.tolist() and search["algorithm"] == "jcbb"
    assert search["nodes"] == jcbb(sc.density, sc.Y).stats["nodes"]
    assert search["expanded"] == search["nodes"] and search["parents_first"] and search["root"] == [-1, -1]


def test_exercise_module_imports_nothing_from_helpers():
    tree = ast.parse((ROOT / "helpers" / "exercises.py").read_text(encoding="utf-8"))
    imported = [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)] + \
        [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    assert not [m for m in imported if m.startswith("helpers") or m.startswith(".")], imported
    assert textwrap.dedent(exercises.message("x", "y")).startswith("exercise x is not implemented yet")


def test_a_rebuild_removes_only_what_the_last_build_wrote(tree, tmp_path):
    dest = student.build(tmp_path / "student", root=tree, quiet=True)
    (dest / ".git").mkdir()
    (dest / ".git" / "HEAD").write_text("ref: refs/heads/main\n", encoding="utf-8")
    (dest / "notes.md").write_text("mine\n", encoding="utf-8")
    (dest / "pkg" / "extra.py").write_text("x = 1\n", encoding="utf-8")
    (tree / "pkg" / "gone.py").write_text("", encoding="utf-8")
    student.build(dest, root=tree, quiet=True)
    assert (dest / "pkg" / "gone.py").exists()
    (tree / "pkg" / "gone.py").unlink()                     # the answer key drops a file: the rebuild drops it too
    student.build(dest, root=tree, quiet=True)
    assert not (dest / "pkg" / "gone.py").exists()
    assert (dest / ".git" / "HEAD").exists() and (dest / "notes.md").read_text(encoding="utf-8") == "mine\n"
    assert (dest / "pkg" / "extra.py").exists() and (dest / "pkg" / "shapes.py").exists()
    student.remove_previous_build(dest)
    assert sorted(p.name for p in dest.iterdir()) == [".git", "notes.md", "pkg"]
    assert [p.name for p in (dest / "pkg").iterdir()] == ["extra.py"]


def test_the_build_refuses_a_folder_it_did_not_make(tree, tmp_path):
    dest = tmp_path / "mine"
    dest.mkdir()
    (dest / "thesis.tex").write_text("\\documentclass{article}\n", encoding="utf-8")
    with pytest.raises(student.BuildError, match="was not built by tools/student.py"):
        student.build(dest, root=tree, quiet=True)
    assert [p.name for p in dest.iterdir()] == ["thesis.tex"]


def test_submission_zip_holds_the_exercise_files_and_notebooks_and_says_what_is_missing(real_edition, tmp_path):
    import zipfile

    import submission

    tree = tmp_path / "student"
    shutil.copytree(real_edition, tree)
    student.copy_solution(tree, "lab8_2a_individual_compatibility")
    nb_path = next(p for p in sorted((tree / "notebooks").glob("*.ipynb"))
                   if "student-answer" in p.read_text(encoding="utf-8"))
    nb = json.loads(nb_path.read_text(encoding="utf-8"))
    cell = next(c for c in nb["cells"] if "student-answer" in c["metadata"].get("tags", []))
    cell["source"] = ["Because the gate follows the covariance."]
    nb_path.write_text(json.dumps(nb), encoding="utf-8")
    files = submission.exercise_files(tree)
    submission.pack(tmp_path / "s.zip", tree)
    names = zipfile.ZipFile(tmp_path / "s.zip").namelist()
    notebooks = ["notebooks/%s" % p.name for p in (tree / "notebooks").glob("*.ipynb")]
    assert sorted(names) == sorted(list(files) + notebooks)
    assert "helpers/association/compatibility.py" in files and not any(n.startswith("tests/") for n in names)
    todo = submission.unwritten(tree, files)
    assert "lab8_2a_individual_compatibility" not in todo and len(todo) == len(student.load_registry()["exercise"]) - 1
    empty, total = submission.empty_answers(tree)
    assert total >= 40 and empty == total - 1
