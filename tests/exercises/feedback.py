"""Checks for the exercise tests that fail with feedback a student can act on.

Every check names what it checks, shows the input it used, the expected and the actual value, and raises
``AssertionError`` with that text (the grader, ``tools/grade.py``, prints it with the exercise's hint). A test
never uses a bare ``assert``: the student would see ``assert False``.

    expect_close(actual, expected, "the predicted pixel of landmark 0", given={"x": x})
    expect_jacobian(lambda x: f(x), x0, J, "∂h/∂x of the bundle")
    expect_raises(ValueError, f, bad, what="a 3 x 5 Y", mentions=["Y"])

``fixture(name)`` loads the recorded inputs of an exercise (``tests/exercises/fixtures/<name>.npz``): values that
other exercises or long runs would produce, written from the answer key by ``tools/exercise_fixtures.py`` and
checked by CI to still equal it, so that every exercise is graded on its own.
"""
from __future__ import annotations

import pathlib
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import numpy as np

FIXTURES = pathlib.Path(__file__).resolve().parent / "fixtures"
_PRINT = {"precision": 6, "suppress_small": True, "max_line_width": 100, "threshold": 60}


def fixture(name: str) -> dict[str, np.ndarray]:
    """The recorded arrays of ``fixtures/<name>.npz`` as a dict (0-d arrays become Python scalars)."""
    path = FIXTURES / ("%s.npz" % name)
    if not path.exists():
        raise FileNotFoundError("grading fixture %s is missing (expected %s)" % (name, path))
    with np.load(path, allow_pickle=False) as data:
        return {k: (data[k].item() if data[k].ndim == 0 else data[k]) for k in data.files}


def show(value: Any) -> str:
    """A short, readable text of a value for a failure message (arrays with 6 significant digits)."""
    if isinstance(value, np.ndarray) or (isinstance(value, (list, tuple)) and value and
                                         all(isinstance(v, (int, float, np.number)) for v in value)):
        arr = np.asarray(value)
        text = np.array2string(arr, **_PRINT)
        return text if arr.ndim <= 1 else "shape %s\n%s" % (arr.shape, text)
    if isinstance(value, Mapping):
        return "\n".join("%s = %s" % (k, _indent(show(v), len(str(k)) + 3)) for k, v in value.items())
    text = repr(value)
    return text if len(text) <= 400 else text[:397] + "..."


def _indent(text: str, n: int) -> str:
    return text.replace("\n", "\n" + " " * n)


def _message(what: str, given=None, expected=None, actual=None, note: str | None = None, *,
             has_expected: bool = True) -> str:
    lines = ["check: %s" % what]
    if given is not None:
        lines.append("  given:    " + _indent(show(given), 12))
    if has_expected:
        lines.append("  expected: " + _indent(show(expected), 12))
        lines.append("  actual:   " + _indent(show(actual), 12))
    if note:
        lines.append("  " + note)
    return "\n".join(lines)


def fail(what: str, *, given=None, expected=None, actual=None, note: str | None = None) -> None:
    """Fail the check ``what`` with whatever of given / expected / actual / note is known."""
    raise AssertionError(_message(what, given, expected, actual, note,
                                  has_expected=expected is not None or actual is not None))


def expect_true(condition: bool, what: str, *, given=None, actual=None, note: str | None = None) -> None:
    """``condition`` must hold; ``actual`` (optional) is the value it was about."""
    if not bool(condition):
        raise AssertionError(_message(what, given, None, actual, note, has_expected=actual is not None)
                             .replace("  expected: None\n", ""))


def expect_equal(actual: Any, expected: Any, what: str, *, given=None) -> None:
    """Exact equality (numbers, bools, strings, integer arrays, tuples of them)."""
    if isinstance(expected, np.ndarray) or isinstance(actual, np.ndarray):
        a, e = np.asarray(actual), np.asarray(expected)
        ok = a.shape == e.shape and bool(np.array_equal(a, e))
        note = None if a.shape == e.shape else "shapes differ: expected %s, got %s" % (e.shape, a.shape)
    else:
        ok, note = actual == expected, None
    if not ok:
        raise AssertionError(_message(what, given, expected, actual, note))


def expect_shape(array: Any, shape: tuple, what: str, *, given=None) -> None:
    """``array`` is a numpy array of ``shape`` (``None`` in ``shape`` matches any length) with finite values."""
    if not isinstance(array, np.ndarray):
        fail(what, given=given, note="expected a numpy array of shape %s, got %s" % (shape, type(array).__name__))
    if array.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, array.shape)):
        fail(what, given=given, note="expected shape %s, got %s" % (shape, array.shape))
    if array.dtype.kind in "fc" and not np.all(np.isfinite(array)):
        fail(what, given=given, actual=array, note="the array has non-finite entries (NaN or inf)")


def expect_close(actual: Any, expected: Any, what: str, *, given=None, rtol: float = 1e-7,
                 atol: float = 1e-9) -> None:
    """``|actual − expected| ≤ atol + rtol |expected|`` elementwise (shapes must agree)."""
    a = np.asarray(actual, dtype=float) if not isinstance(actual, np.ndarray) else actual
    e = np.asarray(expected, dtype=float)
    if a.shape != e.shape:
        raise AssertionError(_message(what, given, expected, actual,
                                      "shapes differ: expected %s, got %s" % (e.shape, np.shape(a))))
    if not np.all(np.isfinite(a)) and np.all(np.isfinite(e)):
        raise AssertionError(_message(what, given, expected, actual, "the result has NaN or inf entries"))
    bad = ~np.isclose(a, e, rtol=rtol, atol=atol)
    if np.any(bad):
        diff = np.where(bad, np.abs(a - e), 0.0)
        at = np.unravel_index(int(np.argmax(diff)), diff.shape) if diff.ndim else ()
        note = "largest difference %.3g%s (tolerance %.0e + %.0e × |expected|)" % (
            float(np.max(diff)), " at index %s" % (tuple(int(i) for i in at),) if at else "", atol, rtol)
        raise AssertionError(_message(what, given, expected, actual, note))


def numeric_jacobian(func: Callable[[np.ndarray], np.ndarray], x: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """Central differences ``(f(x + h e_j) − f(x − h e_j)) / 2h`` of a vector function, column by column."""
    x = np.asarray(x, dtype=float)
    f0 = np.asarray(func(x), dtype=float).ravel()
    jac = np.empty((f0.size, x.size))
    for j in range(x.size):
        dx = np.zeros_like(x)
        dx.flat[j] = step
        jac[:, j] = (np.asarray(func(x + dx), dtype=float).ravel()
                     - np.asarray(func(x - dx), dtype=float).ravel()) / (2 * step)
    return jac


def expect_jacobian(func: Callable[[np.ndarray], np.ndarray], x: np.ndarray, jacobian: Any, what: str, *,
                    given=None, step: float = 1e-6, rtol: float = 1e-5, atol: float = 1e-6) -> None:
    """``jacobian`` equals the central differences of ``func`` at ``x`` (the step's truncation error is
    O(h²) ≈ 1e-12 relative and its round-off ≈ 1e-10 / h: the tolerances sit far above both)."""
    numeric = numeric_jacobian(func, x, step)
    jac = np.asarray(jacobian, dtype=float)
    if jac.shape != numeric.shape:
        fail(what, given=given, note="expected a Jacobian of shape %s, got %s" % (numeric.shape, jac.shape))
    expect_close(jac, numeric, what + " (against central differences)", given=given, rtol=rtol, atol=atol)


def expect_raises(error: type[BaseException], func: Callable, *args, what: str, mentions: Iterable[str] = (),
                  **kwargs) -> BaseException:
    """``func(*args, **kwargs)`` raises ``error`` whose message contains every word of ``mentions``."""
    mentions = list(mentions)
    try:
        func(*args, **kwargs)
    except error as err:
        missing = [m for m in mentions if m not in str(err)]
        if missing:
            fail(what, note="it raised %s(%r), but the message should name %s" % (
                type(err).__name__, str(err), ", ".join(repr(m) for m in missing)))
        return err
    except Exception as err:  # noqa: BLE001 — the wrong error is the feedback
        fail(what, note="expected %s%s, but it raised %s: %s" % (
            error.__name__, " naming %s" % ", ".join(repr(m) for m in mentions) if mentions else "",
            type(err).__name__, err))
    fail(what, note="expected %s%s, but nothing was raised" % (
        error.__name__, " naming %s" % ", ".join(repr(m) for m in mentions) if mentions else ""))
    raise AssertionError("unreachable")
