"""The batch grader (tools/grade_all.py) on synthetic submissions of one exercise.

Unit tests of the zip reading and merging need no grading run. The end-to-end part builds the submissions in a
temporary folder from the answer key's own module file (lab8_2a_individual_compatibility: its tests take seconds)
and grades them in ONE batch (about 20 s on 2 workers: a grading run per submission that reaches the grader),
plus one submission whose first exercise hangs, on its own with short time limits (about 35 s)."""
import json
import pathlib
import shutil
import sys
import zipfile

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

import grade_all  # noqa: E402
import grading_tree  # noqa: E402
import student  # noqa: E402
import submission_files  # noqa: E402

EX = "lab8_2a_individual_compatibility"
OTHER = "lab8_2c_joint_compatibility"     # in the same module file
MODULE = "helpers/association/compatibility.py"
KEY_LINE = "    return density.marginal([2 * j, 2 * j + 1]).is_within_confidence_region(Y[:, i], n_sigma)\n"


def key_source() -> str:
    text = (ROOT / MODULE).read_text(encoding="utf-8")
    assert KEY_LINE in text, "the answer key's line this test plants bugs into has changed"
    return text


def make_zip(path: pathlib.Path, files: dict) -> pathlib.Path:
    with zipfile.ZipFile(path, "w") as zf:
        for name, text in files.items():
            zf.writestr(name, text)
    return path


# ---------------------------------------------------------------------------------------------- unit tests
def test_safe_name_rejects_absolute_and_climbing_paths():
    assert submission_files.safe_name("helpers/a.py") == "helpers/a.py"
    assert submission_files.safe_name("./helpers\\a.py") == "helpers/a.py"
    for bad in ("../helpers/a.py", "/etc/passwd", "helpers/../../x.py", "C:/x.py", ""):
        assert submission_files.safe_name(bad) is None


def test_added_helpers_are_only_new_module_level_functions():
    key = "import numpy as np\nLIMIT = 3\n\ndef f(x):\n    return x\n\nclass C:\n    pass\n"
    mine = key + ("\n@staticmethod\ndef _mine(x):\n    return 2 * x\n\ndef f2():\n    pass\n"
                  "\ndef LIMIT():\n    pass\n\ndef np():\n    pass\n\nclass D:\n    pass\nZ = 1\n")
    extra = submission_files.added_helpers(mine, key)
    assert [e.splitlines()[0] for e in extra] == ["@staticmethod", "def f2():"]


def test_read_modules_reports_missing_unparsable_and_not_a_zip(tmp_path):
    bad = make_zip(tmp_path / "s.zip", {MODULE: "def individual_compatibility(:\n", "../../evil.py": "x = 1\n"})
    sources, problems = submission_files.read_modules(bad, [MODULE, "helpers/features.py"])
    assert sources == {}
    assert "does not parse" in problems[MODULE]
    assert "has no file helpers/features.py" in problems["helpers/features.py"]
    (tmp_path / "t.zip").write_text("not a zip", encoding="utf-8")
    with pytest.raises(ValueError, match="not a readable zip"):
        submission_files.read_modules(tmp_path / "t.zip", [MODULE])


def test_the_grading_process_gets_no_secrets_of_the_instructors_shell(tmp_path, monkeypatch):
    monkeypatch.setenv("GITHUB_TOKEN", "secret")
    monkeypatch.setenv("PYTEST_ADDOPTS", "-p conftest_of_somebody")
    env = grading_tree.grader_env(tmp_path)
    assert "GITHUB_TOKEN" not in env and "PYTEST_ADDOPTS" not in env
    assert env["PYTHONPATH"] == str(tmp_path) and "PATH" in env


def test_numba_cache_is_copied_only_for_unchanged_modules(tmp_path):
    key, tree = tmp_path / "key", tmp_path / "tree"
    for root in (key, tree):
        (root / "helpers" / "__pycache__").mkdir(parents=True)
    for name, text in (("same.py", "x = 1\n"), ("changed.py", "y = 1\n")):
        (key / "helpers" / name).write_text(text, encoding="utf-8")
        (key / "helpers" / "__pycache__" / (name[:-3] + ".f-3.py311.nbi")).write_text("index", encoding="utf-8")
        shutil.copy2(key / "helpers" / name, tree / "helpers" / name)
    (tree / "helpers" / "changed.py").write_text("y = 2\n", encoding="utf-8")
    assert grading_tree.copy_numba_cache(key, tree) == 1
    assert [p.name for p in (tree / "helpers" / "__pycache__").iterdir()] == ["same.f-3.py311.nbi"]


def test_merge_takes_bodies_and_added_helpers_only(tmp_path):
    key, tree = tmp_path / "key" / "m.py", tmp_path / "tree" / "m.py"
    for path in (key, tree):
        path.parent.mkdir()
    key.write_text("import os\n\ndef f(x):\n    \"\"\"Doc.\"\"\"\n    return x\n\ndef g(x):\n    return x\n",
                   encoding="utf-8")
    tree.write_text(key.read_text(encoding="utf-8").replace("return x", "raise NotImplementedError"),
                    encoding="utf-8")
    files = {"ex_f": [("m.py", "f")], "ex_g": [("m.py", "g")]}
    mine = ("import os\nimport subprocess\n\ndef f(x):\n    return _twice(x)\n\ndef g(x): return x\n\n"
            "def _twice(x):\n    return 2 * x\n\ndef os():\n    pass\n\nEVIL = subprocess.run\n")
    problems = submission_files.merge_submission(tree.parent, {"m.py": mine}, files, root=key.parent)
    assert list(problems) == ["ex_g"] and "signature line" in problems["ex_g"]
    merged = tree.read_text(encoding="utf-8")
    assert '"""Doc."""\n    return _twice(x)\n' in merged and "def _twice(x):" in merged
    assert "subprocess" not in merged and "def os" not in merged and merged.count("raise NotImplementedError") == 1
    problems = submission_files.merge_submission(tree.parent, {"m.py": "def g(x):\n    return 1\n"}, files,
                                          root=key.parent)
    assert "no function f" in problems["ex_f"] and "ex_g" not in problems


def test_parse_blocks_splits_the_graders_report():
    text = ("lab8_2a_individual_compatibility   FAILED    1 of 6 checks failed\n  ✗ the gate (test_gate)\n"
            "      expected: 1\n    hint: h\nl09_jcbb   passed    (3 checks)\nexercises: 1 passed, 1 failed\n")
    blocks = grade_all.parse_blocks(text, [EX, "l09_jcbb"])
    assert blocks[EX][0].startswith("FAILED") and "hint: h" in blocks[EX][1]
    assert blocks["l09_jcbb"][0].startswith("passed")


# ---------------------------------------------------------------------------------------------- end to end
@pytest.fixture(scope="module")
def edition(tmp_path_factory) -> pathlib.Path:
    return student.build(tmp_path_factory.mktemp("edition") / "student", quiet=True)


@pytest.fixture(scope="module")
def edition_stub(edition) -> str:
    """The student edition's (untouched) module file."""
    return (edition / MODULE).read_text(encoding="utf-8")


def answered_notebook(edition) -> tuple[str, str, str]:
    """(notebook path, cell id, text): the edition's notebook of the answer key's first answer cell, with that
    cell answered."""
    first = submission_files.answer_cells()[0]
    nb = json.loads((edition / first["notebook"]).read_text(encoding="utf-8"))
    cell = next(c for c in nb["cells"] if c.get("id") == first["cell"])
    assert "student-answer" in cell["metadata"]["tags"]
    cell["source"] = ["My answer: the vectorised gate.\n"]
    return first["notebook"], first["cell"], json.dumps(nb)


@pytest.fixture(scope="module")
def batch(tmp_path_factory, edition, edition_stub):
    subs = tmp_path_factory.mktemp("submissions")
    key = key_source()
    wrong = key.replace(KEY_LINE, KEY_LINE.replace("[2 * j, 2 * j + 1]", "[j, j + 1]"))
    helper = key.replace(KEY_LINE, "    return _gate_of(density, Y, i, j, n_sigma)\n") + (
        "\n\ndef _gate_of(density, Y, i, j, n_sigma):\n"
        "    return density.marginal([2 * j, 2 * j + 1]).is_within_confidence_region(Y[:, i], n_sigma)\n")
    forcing = ("import pytest\n\n@pytest.hookimpl(hookwrapper=True)\ndef pytest_runtest_makereport(item, call):\n"
               "    outcome = yield\n    rep = outcome.get_result()\n    rep.outcome = 'passed'\n")
    notebook, _, answered = answered_notebook(edition)
    make_zip(subs / "correct.zip", {MODULE: key, "notebooks/03_compatibility.ipynb": "{}", notebook: answered})
    make_zip(subs / "wrong.zip", {MODULE: wrong})
    make_zip(subs / "untouched.zip", {MODULE: edition_stub})
    make_zip(subs / "helper.zip", {"./" + MODULE: helper})
    make_zip(subs / "malicious.zip", {
        MODULE: wrong, "tests/conftest.py": forcing, "conftest.py": forcing,
        "tests/exercises/test_%s.py" % EX: "def test_ok():\n    pass\n",
        "tools/grade.py": "print('%s passed (1 checks)')\n" % EX,
        "../../outside.py": "x = 1\n", "/tmp/absolute_grade_all.py": "x = 1\n"})
    unparsable = key.replace("def individual_compatibility(", "def individual_compatibility((")
    make_zip(subs / "syntax.zip", {MODULE: unparsable})
    make_zip(subs / "missing.zip", {"notebooks/03_compatibility.ipynb": "{}"})
    (subs / "notazip.zip").write_text("this is not a zip file", encoding="utf-8")
    seen = []
    out = tmp_path_factory.mktemp("graded")
    results = grade_all.grade_all(subs, out, jobs=2, timeout_per_submission=240, only=[EX],
                                  progress=lambda done, total, r: seen.append((done, total, r["student"])))
    return out, {r["student"]: r for r in results}, seen


def test_batch_scores_every_submission_as_designed(batch):
    out, results, seen = batch
    expected = {"correct": 1, "helper": 1, "wrong": 0, "untouched": 0, "malicious": 0, "syntax": 0, "missing": 0,
                "notazip": 0}
    assert {s: r["total"] for s, r in results.items()} == expected
    assert sorted(s for _, _, s in seen) == sorted(expected) and seen[-1][:2] == (8, 8)
    rows = (out / "grades.csv").read_text(encoding="utf-8").splitlines()
    assert rows[0] == "student,%s,total" % EX
    assert "correct,1,1" in rows and "malicious,0,0" in rows and len(rows) == 9


def test_feedback_gives_the_reason(batch):
    out, _, _ = batch
    feedback = {p.stem: p.read_text(encoding="utf-8") for p in (out / "feedback").glob("*.txt")}
    assert len(feedback) == 8
    assert "not a readable zip" in feedback["notazip"]
    assert "has no file %s" % MODULE in feedback["missing"]
    assert "does not parse as Python" in feedback["syntax"]
    assert "not written yet" in feedback["untouched"]
    assert "FAILED" in feedback["wrong"] and "hint:" in feedback["wrong"]
    assert "passed" in feedback["correct"] and "score: 1 of 1" in feedback["correct"]
    assert "FAILED" in feedback["malicious"]               # its conftest.py, tests and grade.py were not used
    assert not (out.parent / "outside.py").exists() and not pathlib.Path("/tmp/absolute_grade_all.py").exists()


def test_a_hang_scores_zero_with_time_limit_and_the_other_exercise_is_graded(tmp_path):
    """lab8_2a hangs, lab8_2c (same file) is the answer key's: the run of both hits the limit, each runs again
    alone, and only lab8_2a scores 0 (about 35 s: the first limit, the hang's own limit, lab8_2c's run)."""
    hang = key_source().replace(KEY_LINE, "    while True:\n        pass\n")
    path = make_zip(tmp_path / "hang.zip", {MODULE: hang})
    tree = grading_tree.build_grading_tree(tmp_path / "tree")
    result = grade_all.grade_submission(path, tree, student.load_registry(), timeout=5, timeout_per_exercise=20,
                                        only=[EX, OTHER])
    assert result["scores"] == {EX: 0, OTHER: 1}
    assert grade_all.TIME_LIMIT in result["reasons"][EX] and OTHER not in result["reasons"]
    assert "passed" in result["feedback"] and json.dumps(result)      # plain data (what a worker hands back)


def test_written_answers_are_collected_by_the_answer_keys_cell_ids(batch, edition):
    out, results, _ = batch
    notebook, cell, _ = answered_notebook(edition)
    answers = json.loads((out / "answers" / "correct.json").read_text(encoding="utf-8"))
    assert len(answers) == len(submission_files.answer_cells())
    mine = next(a for a in answers if a["cell"] == cell)
    assert mine["status"] == "answered" and mine["answer"] == "My answer: the vectorised gate." and mine["question"]
    same_notebook = [a["status"] for a in answers if a["notebook"] == notebook and a["cell"] != cell]
    assert set(same_notebook) <= {"unanswered"}
    assert {a["status"] for a in answers if a["notebook"] != notebook} == {"missing"}
    assert "written answers (marked by hand): 1 of" in results["correct"]["feedback"]
    assert {a["status"] for a in results["notazip"]["answers"]} == {"missing"}
