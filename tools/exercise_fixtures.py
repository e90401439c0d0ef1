"""Record and verify the grading fixtures of the exercises (answer key only; not in the student edition).

    python tools/exercise_fixtures.py record [NAME ...]   # write tests/exercises/fixtures/NAME.npz
    python tools/exercise_fixtures.py check  [NAME ...]   # recompute, compare with the stored files

An exercise's tests call only that exercise and code that is not an exercise. The inputs another exercise (or
a long run) would produce for them are recorded here, from the answer key, by a *recipe*: a function returning
``{array name: array}``. Recipes live in ``tools/fixture_recipes_<part>.py`` and register themselves with
``@recipe("<fixture name>", rtol=…, atol=…)``; a fixture named ``<exercise>_hidden`` holds the expected values
of the hidden (instructor's) tests and is left out of the student edition. ``tests/test_exercise_fixtures.py``
runs ``check`` in CI: a fixture that no longer equals the answer key within its recipe's tolerance (which follows
the computation's conditioning, not round-off luck) fails it.
"""
from __future__ import annotations

import importlib
import pathlib
import sys
from collections.abc import Callable

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
FIXTURES = ROOT / "tests" / "exercises" / "fixtures"
RECIPE_MODULES = ("fixture_recipes_lab8", "fixture_recipes_l09", "fixture_recipes_q1", "fixture_recipes_q2q3")
RECIPES: dict[str, dict] = {}


def recipe(name: str, *, rtol: float = 1e-9, atol: float = 1e-12) -> Callable:
    """Register ``func() -> {array name: array}`` as the recipe of fixture ``name``."""
    def register(func):
        if name in RECIPES:
            raise ValueError("two recipes for fixture %r" % name)
        RECIPES[name] = {"func": func, "rtol": rtol, "atol": atol}
        return func
    return register


def load_recipes() -> dict:
    """Import every recipe module (each registers its recipes); returns the registry."""
    sys.path.insert(0, str(ROOT))
    sys.path.insert(0, str(ROOT / "tools"))
    sys.modules.setdefault("exercise_fixtures", sys.modules[__name__])   # run as a script: one registry
    for module in RECIPE_MODULES:
        if (ROOT / "tools" / ("%s.py" % module)).exists():
            importlib.import_module(module)
    return RECIPES


def compute(name: str) -> dict[str, np.ndarray]:
    """Run the recipe of ``name``; every value becomes a numpy array (no objects: the files load without pickle)."""
    out = {k: np.asarray(v) for k, v in RECIPES[name]["func"]().items()}
    for key, arr in out.items():
        if arr.dtype == object:
            raise TypeError("fixture %s: %s is not a plain array (dtype object)" % (name, key))
    return out


def path_of(name: str) -> pathlib.Path:
    return FIXTURES / ("%s.npz" % name)


def record(names) -> None:
    FIXTURES.mkdir(parents=True, exist_ok=True)
    for name in names:
        np.savez_compressed(path_of(name), **compute(name))
        print("recorded %s" % path_of(name).relative_to(ROOT))


def differences(name: str) -> list[str]:
    """What differs between the stored fixture ``name`` and the answer key now (empty: equal)."""
    if not path_of(name).exists():
        return ["%s: no stored file (run: python tools/exercise_fixtures.py record %s)" % (name, name)]
    fresh, tol = compute(name), RECIPES[name]
    with np.load(path_of(name), allow_pickle=False) as stored:
        keys = set(stored.files)
        out = ["%s: arrays %s added or removed" % (name, sorted(keys ^ set(fresh)))] if keys != set(fresh) else []
        for key in sorted(keys & set(fresh)):
            old, new = stored[key], fresh[key]
            if old.shape != new.shape or old.dtype.kind != new.dtype.kind:
                out.append("%s.%s: shape/type %s %s -> %s %s" % (name, key, old.shape, old.dtype, new.shape, new.dtype))
            elif new.dtype.kind in "fc":
                if not np.allclose(new, old, rtol=tol["rtol"], atol=tol["atol"], equal_nan=True):
                    out.append("%s.%s: largest difference %.3g" % (name, key, float(np.max(np.abs(new - old)))))
            elif not np.array_equal(new, old):
                out.append("%s.%s: values differ" % (name, key))
    return out


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in ("record", "check"):
        print(__doc__)
        return 2
    recipes = load_recipes()
    names = argv[1:] or sorted(recipes)
    unknown = [n for n in names if n not in recipes]
    if unknown:
        print("no recipe for %s; the fixtures are: %s" % (unknown, ", ".join(sorted(recipes))))
        return 2
    if argv[0] == "record":
        record(names)
        return 0
    problems = [p for n in names for p in differences(n)]
    for p in problems:
        print(p)
    print("fixtures: %d checked, %d differ" % (len(names), len({p.split(":")[0].split(".")[0] for p in problems})))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
