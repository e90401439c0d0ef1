"""Exercises of the student edition: the error an unimplemented exercise raises, and a short notebook message.

The answer key is the workbook itself; ``make student`` (``tools/student.py``) writes the student edition, in
which the body of every exercise function listed in ``tools/exercises.toml`` is replaced by

    raise ExerciseNotImplemented("<exercise name>", "<where its task text is>")

Importing this module inside IPython/Jupyter (the student notebooks do it in their first code cell) installs a
handler that prints one short message for such an error — which exercise, where its task is, how to check it —
instead of a traceback through the workbook's internals. The cell still fails, so "Run all" stops there.

This module imports nothing from ``helpers``: every layer of the package may raise its error.
"""
from __future__ import annotations

import sys

__all__ = ["ExerciseNotImplemented", "message", "install_notebook_handler"]


class ExerciseNotImplemented(NotImplementedError):
    """Raised by the stub of an exercise function the student has not written yet.

    ``exercise`` is the exercise's short name (``make grade EX=<name>`` grades it), ``where`` says where its
    task text is (a section of EXERCISES.md)."""

    def __init__(self, exercise: str, where: str = "EXERCISES.md"):
        self.exercise = str(exercise)
        self.where = str(where)
        super().__init__(message(self.exercise, self.where))


def message(exercise: str, where: str) -> str:
    """The one-paragraph explanation shown for an unimplemented exercise."""
    return (f"exercise {exercise} is not implemented yet. Its task is in {where}. Write the function body, "
            f"then check it with `make grade EX={exercise}` (Windows: `py tools\\workbook.py grade "
            f"{exercise}`) and run this cell again.")


def _notebook_handler(shell, etype, value, tb, tb_offset=None):
    """IPython custom-exception handler: the error shown as one short message instead of a traceback.

    It is sent as the cell's error (``_showtraceback``), so the cell fails — "Run all" and nbval stop there."""
    what = message(getattr(value, "exercise", "?"), getattr(value, "where", "EXERCISES.md"))
    text = f"ExerciseNotImplemented: {what}"
    show = getattr(shell, "_showtraceback", None)
    if show is not None:
        show(etype, value, [text])
    else:
        print(text, file=sys.stderr)
    return []


def install_notebook_handler(shell=None) -> bool:
    """Register the short message with the running IPython shell; False outside IPython (nothing to do)."""
    if shell is None:
        try:
            from IPython import get_ipython
        except ImportError:
            return False
        shell = get_ipython()
    if shell is None or not hasattr(shell, "set_custom_exc"):
        return False
    shell.set_custom_exc((ExerciseNotImplemented,), _notebook_handler)
    return True


if "IPython" in sys.modules:  # cheap test first: a plain Python process never imports IPython for this
    install_notebook_handler()
