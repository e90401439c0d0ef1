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
