"""A synthetic class of 20 submissions for testing and benchmarking the instructor's grader, each with the score
it is designed to get.

    write_class(dest, edition)  ->  {student: (designed score, what it is)}

Each submission is a zip as ``make submission`` writes it (the module files that hold exercise targets), built from
the answer key's own module files by small text edits (a correct student writes the answer key's code), or from the
student edition's files (an untouched submission). What each case does and the exercise groups it is designed to
fail are in CASES; the designed score is the total points minus the points of those groups
(``tools/exercises.toml``). The cases: correct work, a helper function added next to an exercise, untouched, an
empty zip, a file that is not a zip, a syntax error, a missing file, a crash, a hang in Python code, a hang in C
code (no signal gets through), a conftest.py that forces passes with replaced tests and grade.py, a submission that
edits the hidden tests, one that deletes files outside its folder, planted bugs (rows of the marginal, no angle
wrap in Q1c and in Q2b), paths that climb out of the zip, very long output, only Lab 8 done, a helper whose name
the module already has, and a zip written with Windows paths.
"""
from __future__ import annotations

import pathlib
import sys
import zipfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import student  # noqa: E402
import submission_files  # noqa: E402

ROOT = student.ROOT
COMPAT = "helpers/association/compatibility.py"
NN = "helpers/association/nearest_neighbour.py"
EDGES2D = "helpers/graph/edges2d.py"
LAB8_LINE = "    return density.marginal([2 * j, 2 * j + 1]).is_within_confidence_region(Y[:, i], n_sigma)\n"
NN_LINE = '    stats = {"gate": max_distance}\n'
Q1C_LINE = '        e = wrap_angle(x[:, 2] + params["offset"] - z[:, 0])[:, None]\n'
Q2B_LINE = "        e[:, 1] = wrap_angle(np.arctan2(dy, dx) - x[:, 2] - z[:, 1])\n"
FORCING = ("import pytest\n\n@pytest.hookimpl(hookwrapper=True)\ndef pytest_runtest_makereport(item, call):\n"
           "    outcome = yield\n    rep = outcome.get_result()\n    rep.outcome = 'passed'\n")
ALL = "all"
LAB8 = ("lab8_1c_feature_bundle", "lab8_2a_individual_compatibility", "lab8_2c_joint_compatibility",
        "lab8_3a_detect_features")


def edit(text: str, old: str, new: str) -> str:
    """``text`` with the one occurrence of ``old`` replaced (the answer key's line must still be there)."""
    if text.count(old) != 1:
        raise ValueError("the answer key's line %r is not in the module exactly once: update tools/synthetic_class.py"
                         % old.strip())
    return text.replace(old, new)


def _cases(key: dict, stubs: dict, sentinel: pathlib.Path) -> list:
    """[(student, files {zip member: text} or bytes, {exercise: [failing group ids] or ALL}, what it is)]."""
    def with_(rel, old, new):
        return {**key, rel: edit(key[rel], old, new)}

    rows = LAB8_LINE.replace("[2 * j, 2 * j + 1]", "[j, j + 1]")
    helper = edit(key[COMPAT], LAB8_LINE, "    return _gate_of(density, Y, i, j, n_sigma)\n") + (
        "\n\ndef _gate_of(density, Y, i, j, n_sigma):\n" + LAB8_LINE.replace("    return", "    return", 1))
    delete = ("    import os\n    os.remove(%r)\n" % str(sentinel)) + LAB8_LINE
    lab8_only = {rel: (key[rel] if rel in (COMPAT, "helpers/state_slam.py", "helpers/features.py") else stubs[rel])
                 for rel in key}
    clash = key[EDGES2D] + "\n\ndef wrap_angle(a):\n    return a\n"
    return [
        ("correct", key, {}, "the answer key's code"),
        ("helper", {**key, COMPAT: helper}, {}, "lab8_2a through a helper function the student added"),
        ("untouched", stubs, ALL, "the student edition as handed out"),
        ("empty", {}, ALL, "a zip with no file"),
        ("notazip", b"this is not a zip file", ALL, "not a zip"),
        ("syntax", with_(COMPAT, "def individual_compatibility(", "def individual_compatibility(("),
         {"lab8_2a_individual_compatibility": ALL, "lab8_2c_joint_compatibility": ALL}, "a syntax error"),
        ("missing", {r: t for r, t in key.items() if r != EDGES2D},
         {"cw_q1c_compass_fix": ALL, "cw_q1d_gps": ALL, "cw_q2b_range_bearing": ALL}, "edges2d.py missing"),
        ("crash", with_(COMPAT, LAB8_LINE, "    return 1 / 0\n"), {"lab8_2a_individual_compatibility": ALL},
         "lab8_2a raises ZeroDivisionError"),
        ("hang", with_(NN, NN_LINE, "    while True:\n        pass\n"), {"l09_euclidean_nn": ALL},
         "l09_euclidean_nn loops for ever in Python"),
        ("hang_c", with_(NN, NN_LINE, "    sum(range(10 ** 15))\n"), {"l09_euclidean_nn": ALL},
         "l09_euclidean_nn loops for ever in C (no signal is handled)"),
        ("malicious", {**with_(COMPAT, LAB8_LINE, rows), "conftest.py": FORCING, "tests/conftest.py": FORCING,
                       "tests/exercises/test_lab8_2a_individual_compatibility.py": "def test_ok():\n    pass\n",
                       "tools/grade.py": "print('lab8_2a_individual_compatibility passed (1 checks)')\n"},
         {"lab8_2a_individual_compatibility": ["landmark_marginal", "lab_values_hidden"]},
         "wrong rows, with a conftest.py forcing passes, a replaced test and a replaced grade.py"),
        ("edits_tests", {**with_(EDGES2D, Q1C_LINE, Q1C_LINE.replace("wrap_angle(", "(")),
                         "tests/exercises/test_cw_q1c_compass_fix_hidden.py": "def test_ok():\n    pass\n",
                         "tests/exercises/test_cw_q1c_compass_fix.py": "def test_ok():\n    pass\n"},
         {"cw_q1c_compass_fix": ["angle_wrap", "q1c_run_hidden"]}, "Q1c not wrapped, with its tests replaced"),
        ("deletes", with_(COMPAT, LAB8_LINE, delete), {"lab8_2a_individual_compatibility": ALL},
         "lab8_2a deletes a file outside its folder"),
        ("wrong_rows", with_(COMPAT, LAB8_LINE, rows),
         {"lab8_2a_individual_compatibility": ["landmark_marginal", "lab_values_hidden"]}, "lab8_2a: rows j, j+1"),
        ("wrong_q2b", with_(EDGES2D, Q2B_LINE, Q2B_LINE.replace("wrap_angle(", "(")),
         {"cw_q2b_range_bearing": ["bearing_wrap", "q2b_edges_hidden"]}, "Q2b: the bearing error not wrapped"),
        ("traversal", {**key, "../../outside_grading.py": "x = 1\n", "/tmp/absolute_grading.py": "x = 1\n"}, {},
         "correct, with zip members that climb out or are absolute"),
        ("loud", with_(COMPAT, LAB8_LINE, "    print('x' * 200_000)\n" + LAB8_LINE), {},
         "correct, printing 200 000 characters per call"),
        ("lab8_only", lab8_only, {ex: ALL for ex in _names() if ex not in LAB8}, "only Lab 8 done"),
        ("clash", {**key, EDGES2D: clash}, {}, "correct, plus a helper named like the module's own wrap_angle"),
        ("windows", {r.replace("/", "\\"): t for r, t in key.items()}, {}, "correct, zipped with Windows paths"),
    ]


def _names(root=ROOT) -> list:
    return [ex["name"] for ex in student.load_registry(root)["exercise"]]


def designed_score(failing: dict | str, root=ROOT, only=None) -> float:
    """Total points (of the exercises ``only``, default all) minus the points of the failing groups ({exercise:
    [group ids] or ALL}, or ALL)."""
    total = 0.0
    for ex in student.load_registry(root)["exercise"]:
        if only and ex["name"] not in only:
            continue
        fails = ALL if failing == ALL else failing.get(ex["name"], [])
        for gid, group in ex["groups"].items():
            if fails != ALL and gid not in fails:
                total += group["points"]
        if fails != ALL and set(fails) - set(ex["groups"]):
            raise ValueError("unknown groups %s of %s" % (sorted(set(fails) - set(ex["groups"])), ex["name"]))
    return total


def write_class(dest, edition, root=ROOT, only=None) -> dict:
    """Write the 20 zips into ``dest`` (a folder); ``edition`` is a built student edition (its stubs). Returns
    {student: (designed score, what it is)}, the score over the exercises ``only`` (default all). The "deletes"
    case tries to delete ``dest/../SENTINEL`` (created)."""
    dest, edition = pathlib.Path(dest), pathlib.Path(edition)
    dest.mkdir(parents=True, exist_ok=True)
    rels = sorted({r for targets in submission_files.exercise_files(student.load_registry(root), root).values()
                   for r, _ in targets})
    key = {r: (pathlib.Path(root) / r).read_text(encoding="utf-8") for r in rels}
    stubs = {r: (edition / r).read_text(encoding="utf-8") for r in rels}
    sentinel = dest.parent / "SENTINEL"
    sentinel.write_text("the deleting submission must not remove this file\n", encoding="utf-8")
    out = {}
    for name, files, failing, what in _cases(key, stubs, sentinel):
        path = dest / ("%s.zip" % name)
        if isinstance(files, bytes):
            path.write_bytes(files)
        else:
            with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
                for member, text in files.items():
                    zf.writestr(member, text)
        out[name] = (designed_score(failing, root, only), what)
    return out
