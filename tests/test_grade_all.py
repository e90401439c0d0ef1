"""The instructor's grader (tools/grade_all.py, grading_tree.py, submission_files.py, grade_guard.py, gradescope.py)
on synthetic submissions (tools/synthetic_class.py: each kind of bad submission, with its designed score).

Unit tests of the zip reading, merging, scoring and guard need no grading run. The end-to-end part grades one
exercise (lab8_2a_individual_compatibility: its tests take seconds) of 14 submissions in ONE batch, the hangs
on their own with short time limits, and runs the Gradescope autograder's run_autograder in a folder laid out
like /autograder (about 2 min in all)."""
import json
import os
import pathlib
import shutil
import subprocess
import sys
import zipfile

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

import grade_all  # noqa: E402
import gradescope  # noqa: E402
import grading_tree  # noqa: E402
import student  # noqa: E402
import submission_files  # noqa: E402
import synthetic_class  # noqa: E402

pytestmark = pytest.mark.cpu_independent   # grading logic and files; the exercises' numbers are tested elsewhere

EX = "lab8_2a_individual_compatibility"
OTHER = "lab8_2c_joint_compatibility"     # in the same module file
NN = "l09_euclidean_nn"
MODULE = synthetic_class.COMPAT
KEY_LINE = synthetic_class.LAB8_LINE
BATCH = ["correct", "helper", "untouched", "empty", "notazip", "syntax", "missing", "crash", "malicious", "deletes",
         "wrong_rows", "traversal", "loud", "windows"]


def key_source() -> str:
    return (ROOT / MODULE).read_text(encoding="utf-8")


def marked(feedback: str, mark: str, text: str) -> bool:
    """Whether a line of ``feedback`` starts with ``mark`` (✓ or ✗) and holds ``text``."""
    return any(line.lstrip().startswith(mark) and text in line for line in feedback.splitlines())


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


def test_the_grading_process_gets_no_secrets_and_its_own_home(tmp_path, monkeypatch):
    monkeypatch.setenv("GITHUB_TOKEN", "secret")
    monkeypatch.setenv("PYTEST_ADDOPTS", "-p conftest_of_somebody")
    (tmp_path / "tree").mkdir()
    env = grading_tree.grader_env(tmp_path / "tree")
    assert "GITHUB_TOKEN" not in env and "PYTEST_ADDOPTS" not in env
    assert env["PYTHONPATH"] == str(tmp_path / "tree") and "PATH" in env
    assert env["HOME"] == str(tmp_path / "home") and env["TMPDIR"] == str(tmp_path / "tmp")


def test_scores_are_per_group_and_a_group_needs_all_its_checks():
    ex = {"name": "ex", "points": 3, "hints": {"test_b": "look at b"},
          "groups": {"one": {"title": "one", "points": 1, "tests": ["test_a"]},
                     "two": {"title": "two", "points": 2, "tests": ["test_b", "test_c"]}}}
    path = "tests/exercises/test_ex.py::"
    outcomes = {path + "test_a": "passed", path + "test_b[0]": "passed", path + "test_b[1]": "failed",
                "tests/exercises/test_ex_hidden.py::test_c": "passed",
                "tests/exercises/test_other.py::test_b": "passed"}
    failures = {"tests/exercises/test_ex.py::test_b[1]": {"title": "the b check", "text": "expected: 1\nactual: 2"}}
    groups = grading_tree.score_groups(ex, outcomes, ROOT, failures=failures)
    assert [(g["score"], g["failed"]) for g in groups] == [(1.0, []), (0.0, ["test_b"])]
    assert "the b check" in groups[1]["output"] and "actual: 2" in groups[1]["output"]
    assert "look at b" in groups[1]["output"]
    del outcomes[path + "test_a"]                  # a check that did not run
    assert grading_tree.score_groups(ex, outcomes, ROOT)[0]["score"] == 0.0
    assert [g["score"] for g in grading_tree.score_groups(ex, {}, ROOT, reason="time limit")] == [0.0, 0.0]


def test_the_guard_stops_changes_outside_the_work_folder_and_new_programs(tmp_path):
    work, outside = tmp_path / "work", tmp_path / "outside.txt"
    work.mkdir()
    outside.write_text("keep", encoding="utf-8")
    script = work / "attempt.py"
    script.write_text(
        "import os, pathlib, shutil, subprocess\n"
        "def attempt(f):\n    try:\n        f()\n        return 'done'\n    except PermissionError:\n"
        "        return 'stopped'\n"
        "print(attempt(lambda: os.remove(%r)), attempt(lambda: open(%r, 'a')),\n"
        "      attempt(lambda: shutil.rmtree(%r)), attempt(lambda: subprocess.run(['python', '-V'])),\n"
        "      attempt(lambda: pathlib.Path('inside.txt').write_text('x')), open(%r).read())\n"
        % (str(outside), str(outside), str(tmp_path), str(outside)), encoding="utf-8")
    out = subprocess.run([sys.executable, str(ROOT / "tools" / "grade_guard.py"), str(work), str(script)],
                         cwd=str(work), capture_output=True, text=True, timeout=60)
    assert out.stdout.split() == ["stopped", "stopped", "stopped", "stopped", "done", "keep"], out.stderr
    assert outside.read_text(encoding="utf-8") == "keep" and (work / "inside.txt").exists()


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


def test_gradescope_results_hide_the_hidden_groups_until_published():
    groups = [{"title": "public", "points": 1.0, "score": 1.0, "hidden": False, "output": ""},
              {"title": "values", "points": 2.0, "score": 0.0, "hidden": True, "output": "expected: 3"}]
    result = {"groups": {EX: groups}, "reasons": {}, "possible": 3.0, "answers": []}
    data = gradescope.results_json(result, [{"name": EX}])
    assert [(t["score"], t["max_score"], t["visibility"]) for t in data["tests"]] == [
        (1.0, 1.0, "visible"), (0.0, 2.0, "after_published")]
    assert "1 of 1" in data["output"] and "expected: 3" not in data["output"]


@pytest.mark.skipif(os.name == "nt", reason="symbolic links need extra rights on Windows; Gradescope runs Linux")
def test_a_folder_upload_is_packed_without_following_links(tmp_path):
    upload = tmp_path / "submission"
    (upload / "helpers" / "association").mkdir(parents=True)
    (upload / "helpers" / "association" / "compatibility.py").symlink_to(ROOT / MODULE)
    (upload / "helpers" / "features.py").write_text("x = 1\n", encoding="utf-8")
    (upload / "notes.txt").write_text("n", encoding="utf-8")
    packed = gradescope.submission_zip(upload, tmp_path)
    assert zipfile.ZipFile(packed).namelist() == ["helpers/features.py"]
    single = tmp_path / "single"
    single.mkdir()
    make_zip(single / "mine.zip", {"helpers/features.py": "x = 1\n"})
    assert gradescope.submission_zip(single, tmp_path) == single / "mine.zip"


# ---------------------------------------------------------------------------------------------- end to end
@pytest.fixture(scope="module")
def edition(tmp_path_factory) -> pathlib.Path:
    return student.build(tmp_path_factory.mktemp("edition") / "student", quiet=True)


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory, edition) -> tuple[pathlib.Path, dict]:
    """The 20 zips of tools/synthetic_class.py with their designed scores for lab8_2a alone."""
    folder = tmp_path_factory.mktemp("class") / "all"
    return folder, synthetic_class.write_class(folder, edition, only=[EX])


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
def batch(tmp_path_factory, edition, synthetic):
    folder, design = synthetic
    subs = tmp_path_factory.mktemp("submissions")
    for name in BATCH:
        shutil.copy2(folder / ("%s.zip" % name), subs)
    notebook, _, answered = answered_notebook(edition)
    with zipfile.ZipFile(subs / "correct.zip", "a") as zf:
        zf.writestr(notebook, answered)
    seen = []
    out = tmp_path_factory.mktemp("graded")
    results = grade_all.grade_all(subs, out, jobs=2, timeout_per_submission=240, only=[EX],
                                  progress=lambda done, total, r: seen.append((done, total, r["student"])))
    return out, {r["student"]: r for r in results}, seen, design


def test_batch_scores_every_submission_as_designed(batch):
    out, results, seen, design = batch
    assert {s: r["total"] for s, r in results.items()} == {s: design[s][0] for s in BATCH}
    assert {s: design[s][0] for s in ("correct", "malicious", "untouched")} == {"correct": 5, "malicious": 2,
                                                                                "untouched": 0}
    assert sorted(s for _, _, s in seen) == sorted(BATCH) and seen[-1][:2] == (len(BATCH), len(BATCH))
    rows = (out / "grades.csv").read_text(encoding="utf-8").splitlines()
    n_answers = len(submission_files.answer_cells())
    assert rows[0] == "student,%s,total,written answers" % EX and rows[-1] == "(max),5,5,%d" % n_answers
    assert "correct,5,5,1" in rows and "malicious,2,2,0" in rows and len(rows) == len(BATCH) + 2


def test_feedback_gives_the_reason_the_groups_and_every_failed_check(batch):
    out = batch[0]
    feedback = {p.stem: p.read_text(encoding="utf-8") for p in (out / "feedback").glob("*.txt")}
    assert sorted(feedback) == sorted(BATCH)
    assert "not a readable zip" in feedback["notazip"] and "has no file %s" % MODULE in feedback["empty"]
    assert "does not parse as Python" in feedback["syntax"]
    assert "not written yet" in feedback["untouched"]
    assert "ZeroDivisionError" in feedback["crash"] and "raised at helpers" in feedback["crash"]
    wrong = feedback["wrong_rows"]
    assert "score: 2 of 5" in wrong and marked(wrong, "✗", "landmark j's own rows")
    assert marked(wrong, "✓", "a plain bool")
    assert "[hidden]" in wrong and wrong.count("hint:") >= 3 and "actual" in wrong
    assert "score: 5 of 5" in feedback["correct"] and "score: 5 of 5" in feedback["loud"]
    assert "score: 2 of 5" in feedback["malicious"]        # its conftest.py, tests and grade.py were not used
    assert "PermissionError" in feedback["deletes"] and "outside the submission's folder" in feedback["deletes"]
    assert len(feedback["loud"]) < 2 * grading_tree.MAX_OUTPUT_CHARS
    assert "not written yet" in feedback["untouched"] and "grader's report" not in feedback["untouched"]


def test_the_public_feedback_shows_no_hidden_check(batch):
    """What a student may see before the deadline: the public groups with every failed check, the hidden ones
    only as a number of points."""
    out = batch[0]
    public = (out / "feedback-public" / "wrong_rows.txt").read_text(encoding="utf-8")
    assert "score of the public checks: 2 of 3.5 (the hidden checks, 1.5 points" in public
    assert marked(public, "✗", "0 / 1.5  landmark j's own rows") and "actual" in public and "hint:" in public
    assert "[hidden]" not in public and "hidden.py" not in public and "lab template" not in public


def test_nothing_outside_the_grading_folders_was_touched(batch, synthetic):
    folder = synthetic[0]
    assert (folder.parent / "SENTINEL").exists()            # the deleting submission's target
    assert not (batch[0].parent / "outside_grading.py").exists()
    assert not pathlib.Path("/tmp/absolute_grading.py").exists()


@pytest.mark.parametrize("case", ["hang", "hang_c"])
def test_a_hang_hits_the_check_time_limit_and_costs_only_its_exercise(synthetic, case):
    """A loop in Python or in C (no signal gets through sum(range(10**15))): the check is stopped at its limit and
    ends the run; lab8_2a, graded before it in the same run, keeps its points."""
    tree = grading_tree.build_grading_tree(synthetic[0].parent / ("tree-%s" % case))
    result = grade_all.grade_submission(synthetic[0] / ("%s.zip" % case), tree, student.load_registry(),
                                        timeout=120, only=[NN, EX], test_limit=3, with_answers=False)
    assert result["scores"] == {NN: 0, EX: 5}
    assert "time limit: the check" in result["reasons"][NN] and "longer than 3 s" in result["reasons"][NN]
    assert EX not in result["reasons"] and result["seconds"] < 60
    assert json.dumps(result)                                 # plain data (what a worker hands back)


def test_a_module_that_fails_to_import_costs_only_the_exercises_that_use_it(tmp_path, synthetic):
    """An added helper whose default argument raises at import breaks every test file importing its module; the
    other test files still run (lab8_3a lives in helpers/features.py)."""
    features = "lab8_3a_detect_features"
    with zipfile.ZipFile(synthetic[0] / "correct.zip") as zf:
        files = {n: zf.read(n).decode("utf-8") for n in zf.namelist()}
    files[MODULE] += "\n\ndef _my_helper(x=1 / 0):\n    return x\n"
    path = make_zip(tmp_path / "import_error.zip", files)
    tree = grading_tree.build_grading_tree(tmp_path / "tree")
    result = grade_all.grade_submission(path, tree, student.load_registry(), timeout=120, only=[EX, features],
                                        with_answers=False)
    assert result["scores"] == {EX: 0, features: 5}
    assert "does not import" in result["feedback"] and "ZeroDivisionError" in result["feedback"]


def test_a_run_over_its_time_limit_is_killed_whole(synthetic):
    tree = grading_tree.build_grading_tree(synthetic[0].parent / "tree-run-limit")
    result = grade_all.grade_submission(synthetic[0] / "hang_c.zip", tree, student.load_registry(), timeout=8,
                                        only=[NN], test_limit=600, with_answers=False)
    assert result["scores"] == {NN: 0} and grade_all.TIME_LIMIT in result["reasons"][NN]
    assert "grading stopped after 8 s" in result["reasons"][NN] and result["seconds"] < 30


def test_written_answers_are_collected_by_the_answer_keys_cell_ids(batch, edition):
    out, results, _, _ = batch
    notebook, cell, _ = answered_notebook(edition)
    answers = json.loads((out / "answers" / "correct.json").read_text(encoding="utf-8"))
    assert len(answers) == len(submission_files.answer_cells())
    mine = next(a for a in answers if a["cell"] == cell)
    assert mine["status"] == "answered" and mine["answer"] == "My answer: the vectorised gate." and mine["question"]
    assert {a["status"] for a in answers if a["notebook"] != notebook} == {"missing"}
    assert "written answers (marked by hand): 1 of" in results["correct"]["feedback"]
    assert {a["status"] for a in results["notazip"]["answers"]} == {"missing"}


@pytest.mark.skipif(os.name == "nt", reason="run_autograder is a bash script: Gradescope runs Linux")
def test_the_gradescope_autograder_gives_grade_alls_scores(tmp_path, batch, synthetic):
    """The zip is unpacked into a folder laid out like /autograder and its run_autograder grades the correct
    submission (all exercises); the wrong one, uploaded as a folder, is graded for lab8_2a as grade-all did."""
    ag = tmp_path / "autograder"
    with zipfile.ZipFile(gradescope.build(tmp_path / "autograder.zip")) as zf:
        zf.extractall(ag / "source")
        assert {"setup.sh", "run_autograder", "requirements.txt"} <= set(zf.namelist())
    (ag / "submission").mkdir()
    shutil.copy2(synthetic[0] / "correct.zip", ag / "submission")
    env = dict(os.environ, AUTOGRADER_ROOT=str(ag), AUTOGRADER_PYTHON=sys.executable)
    subprocess.run(["bash", str(ag / "source" / "run_autograder")], env=env, check=True, timeout=600,
                   capture_output=True)
    data = json.loads((ag / "results" / "results.json").read_text(encoding="utf-8"))
    assert sum(t["score"] for t in data["tests"]) == sum(t["max_score"] for t in data["tests"]) == 84
    assert {t["visibility"] for t in data["tests"] if "hidden" in t["name"] or "[hidden]" in t["output"]} <= {
        "after_published"}
    hidden = [g["hidden"] for ex in student.load_registry()["exercise"] for g in grading_tree.groups_of(ex)]
    assert [t["visibility"] == "after_published" for t in data["tests"]] == hidden and sum(hidden) >= 15
    shutil.rmtree(ag / "submission")
    with zipfile.ZipFile(synthetic[0] / "wrong_rows.zip") as zf:
        zf.extractall(ag / "submission")
    data = gradescope.run(ag, only=[EX])
    assert sum(t["score"] for t in data["tests"]) == batch[1]["wrong_rows"]["total"] == 2
