"""Notebook support: checks of the prose that respect a student's parameters, and showing the running code.

Every notebook's parameter cell ends with ``claims = Claims(globals(), SEED=0, CLUTTER=5)`` (the defaults the prose
was written for); ``claims.check(condition, "what the text says")`` raises at the defaults when the claim is false
and prints a note once a student changed a parameter. ``show_source(obj)`` displays the source that runs.
"""
from __future__ import annotations

import inspect
import math
import numbers
import textwrap

__all__ = ["Claims", "show_source", "source_lines"]


def _same(a, b) -> bool:
    """Equality of two parameter values (numbers compared as numbers, sequences element-wise)."""
    if isinstance(a, numbers.Number) and isinstance(b, numbers.Number):
        return a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b


class Claims:
    """Checks of a notebook's prose: strict at the default parameters, a printed note otherwise.

    Parameters
    ----------
    namespace : the notebook's ``globals()`` (the parameter values are read from it once, now)
    **defaults : each parameter's name and the default value the prose was written for
    """

    def __init__(self, namespace: dict, **defaults: object) -> None:
        if not isinstance(namespace, dict):
            raise ValueError(f"namespace must be the notebook's globals() dict, got {type(namespace).__name__}")
        if not defaults:
            raise ValueError("name at least one parameter and its default, e.g. Claims(globals(), SEED=0)")
        missing = [name for name in defaults if name not in namespace]
        if missing:
            raise ValueError(f"parameters {missing} are not defined in the notebook (define them before Claims)")
        self.defaults = dict(defaults)
        self.values = {name: namespace[name] for name in defaults}
        self.changed = [name for name in defaults if not _same(self.values[name], defaults[name])]
        self.failed: list[str] = []

    @property
    def at_defaults(self) -> bool:
        """True when every parameter has the value the prose was written for."""
        return not self.changed

    def check(self, condition: object, claim: str) -> bool:
        """Guard one claim of the text; returns the condition as a bool.

        At the defaults a false claim raises AssertionError naming it; with changed parameters it prints
        ``note (your parameters …): no longer holds: <claim>`` once and returns False. ``condition`` is one truth
        value (numpy raises ValueError for an array of several).
        """
        if not isinstance(claim, str) or not claim:
            raise ValueError("claim must be a non-empty string saying what the text claims")
        ok = bool(condition)
        if not ok:
            if self.at_defaults:
                raise AssertionError(f"the text claims: {claim}")
            if claim not in self.failed:
                self.failed.append(claim)
                print(f"note (your parameters {', '.join(self.changed)}): no longer holds: {claim}")
        return ok

    def __repr__(self) -> str:
        state = "defaults" if self.at_defaults else f"changed: {', '.join(self.changed)}"
        return f"Claims({state}; {len(self.failed)} claim(s) no longer hold)"


def source_lines(obj: object) -> str:
    """The source text of a function, method or class, dedented (raises ValueError if it has none)."""
    target = inspect.unwrap(obj)
    if isinstance(target, (staticmethod, classmethod)):
        target = target.__func__
    try:
        text = inspect.getsource(target)
    except (OSError, TypeError) as err:
        raise ValueError(f"no Python source is available for {obj!r}: {err}") from None
    return textwrap.dedent(text)


def show_source(obj: object, start: str | None = None, stop: str | None = None) -> None:
    """Display the source of ``obj`` (syntax-highlighted in Jupyter, plain text elsewhere).

    ``start`` / ``stop``: show only the lines from the first one containing ``start`` up to (excluding) the first
    later one containing ``stop``; None means from the first line / to the end. A string that no line contains
    raises ValueError.
    """
    for arg, value in (("start", start), ("stop", stop)):
        if value is not None and (not isinstance(value, str) or not value):
            raise ValueError(f"{arg} must be a non-empty string or None, got {value!r}")
    text = source_lines(obj)
    if start is not None or stop is not None:
        lines = text.splitlines()
        first = next((i for i, line in enumerate(lines) if start is None or start in line), None)
        if first is None:
            raise ValueError(f"no line of {getattr(obj, '__qualname__', obj)} contains start {start!r}")
        last = next((i for i in range(first + 1, len(lines)) if stop is not None and stop in lines[i]), None)
        if last is None and stop is not None:
            raise ValueError(f"no line of {getattr(obj, '__qualname__', obj)} after {start!r} contains stop {stop!r}")
        last = len(lines) if last is None else last
        text = textwrap.dedent("\n".join(lines[first:last])) + "\n"
    name = getattr(obj, "__qualname__", getattr(obj, "__name__", repr(obj)))
    module = getattr(inspect.unwrap(obj), "__module__", "")
    header = f"# {module}.{name}" if module else f"# {name}"
    try:
        from IPython.display import Code, display
    except ImportError:  # outside Jupyter
        print(header + "\n" + text)
        return
    display(Code(header + "\n" + text, language="python"))
