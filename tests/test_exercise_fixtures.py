"""The grading fixtures still equal the answer key (tools/exercise_fixtures.py; issue 37, part A)."""
from __future__ import annotations

import pathlib
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tools"))
import exercise_fixtures  # noqa: E402

RECIPES = exercise_fixtures.load_recipes()


@pytest.mark.parametrize("name", sorted(RECIPES))
def test_fixture_equals_the_answer_key(name):
    problems = exercise_fixtures.differences(name)
    assert not problems, "\n".join(problems) + "\n(re-record: python tools/exercise_fixtures.py record %s)" % name


def test_every_exercise_has_public_tests_and_no_fixture_is_orphaned():
    import tomllib

    with open("tools/exercises.toml", "rb") as fh:
        names = [ex["name"] for ex in tomllib.load(fh)["exercise"]]
    folder = exercise_fixtures.ROOT / "tests" / "exercises"
    missing = [n for n in names if not (folder / ("test_%s.py" % n)).exists()]
    assert not missing, "exercises without tests/exercises/test_<name>.py: %s" % missing
    stored = {p.stem for p in exercise_fixtures.FIXTURES.glob("*.npz")}
    orphans = sorted(stored - set(RECIPES))
    assert not orphans, "fixture files without a recipe: %s" % orphans


def test_every_check_of_every_exercise_has_a_hint():
    """The grader prints the registry's hint under each failed check (issue 37, part B): none may be missing."""
    import re
    import tomllib

    with open("tools/exercises.toml", "rb") as fh:
        exercises = tomllib.load(fh)["exercise"]
    folder = exercise_fixtures.ROOT / "tests" / "exercises"
    missing = {}
    for ex in exercises:
        names = set()
        for path in folder.glob("test_%s*.py" % ex["name"]):
            if re.fullmatch(r"test_%s(_hidden)?\.py" % ex["name"], path.name):
                names |= set(re.findall(r"(?m)^def (test_\w+)", path.read_text(encoding="utf-8")))
        unknown = set(ex.get("hints", {})) - names
        if names - set(ex.get("hints", {})) or unknown:
            missing[ex["name"]] = {"without a hint": sorted(names - set(ex.get("hints", {}))),
                                   "hint for no test": sorted(unknown)}
    assert not missing, missing


def test_every_check_of_every_exercise_is_in_one_scored_group():
    """The instructor's grader scores per test group (issue 38, part C): each test function in exactly one group,
    a group all public or all hidden, group points adding up to the exercise's points."""
    import re
    import tomllib

    with open("tools/exercises.toml", "rb") as fh:
        exercises = tomllib.load(fh)["exercise"]
    folder = exercise_fixtures.ROOT / "tests" / "exercises"
    problems = {}
    for ex in exercises:
        hidden_of = {}
        for suffix, hidden in (("", False), ("_hidden", True)):
            path = folder / ("test_%s%s.py" % (ex["name"], suffix))
            if path.exists():
                hidden_of.update({n: hidden for n in re.findall(r"(?m)^def (test_\w+)", path.read_text("utf-8"))})
        grouped = [t for g in ex.get("groups", {}).values() for t in g["tests"]]
        mixed = [gid for gid, g in ex.get("groups", {}).items() if len({hidden_of.get(t) for t in g["tests"]}) != 1]
        total = sum(g["points"] for g in ex.get("groups", {}).values())
        if sorted(grouped) != sorted(hidden_of) or mixed or abs(total - ex.get("points", -1)) > 1e-9:
            problems[ex["name"]] = {"not grouped": sorted(set(hidden_of) - set(grouped)),
                                    "twice or unknown": sorted(t for t in set(grouped)
                                                               if grouped.count(t) > 1 or t not in hidden_of),
                                    "public and hidden mixed": mixed, "group points": total,
                                    "points": ex.get("points")}
    assert not problems, problems
