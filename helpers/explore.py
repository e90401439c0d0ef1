"""Interactive explorations: knobs (ipywidgets) that redraw one matplotlib figure. In a notebook cell::

    from helpers.explore import explore, slider, choice, toggle

    def draw(fig, yaw_sigma, gate, ellipses):     # draws on fig (cleared before each call); precompute outside
        ax = fig.subplots()
        ...
    explore(draw, yaw_sigma=slider(0.0, 5.0, 0.5, value=1.0), gate=choice([0.9, 0.95, 0.99], value=0.95),
            ellipses=toggle(True))

One code path everywhere, no environment switch, so strict nbval checks what a student runs. The cell shows two
outputs: the knobs (a widget) and the figure drawn at the defaults (a PNG with a display id). Both text/plain
reprs are written here from the default values, and nbval skips image/png and the widget view (its model id is
random), so a headless run (nbval, ``tools/workbook.py execute``, ``make figures``) stores and compares the same
outputs every time. Moving a knob in JupyterLab redraws the same Figure and replaces the PNG in place
(update_display_data). Where no widget front end listens (headless runs, a bare kernel), the knobs' messages go
nowhere and the figure stays at the defaults; outside IPython the figure is drawn and returned, nothing shown.
The Figure lives outside pyplot (shown once, never kept by pyplot); running the cell again closes the previous
exploration of the same draw function and knobs (its widgets and figure).
"""
from __future__ import annotations

import base64
import decimal
import html
import io
import math
import numbers
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from matplotlib.figure import Figure
from matplotlib.transforms import Bbox

from .validation import function

__all__ = ["Knob", "slider", "choice", "toggle", "explore", "Exploration", "CROP_MARGIN"]
#: inches added around the first draw's tight box (room for tick labels that grow as a knob moves)
CROP_MARGIN = 0.2


@dataclass(frozen=True)
class Knob:
    """A knob: ``kind`` "slider" (``options`` (lo, hi, step)), "choice" (``options`` ((label, value), ...)) or
    "toggle"; ``value`` is the default, ``label`` the text beside it (None: the parameter's name)."""
    kind: str
    value: Any
    options: tuple = ()
    label: str | None = None


def _real(v: Any) -> bool:  # a finite number, not a bool
    return isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)


def slider(lo: float, hi: float, step: float, value: float | None = None, *, label: str | None = None) -> Knob:
    """A slider from ``lo`` to ``hi`` in steps of ``step`` (an integer slider if all are ints); default ``value``
    (None: ``lo``)."""
    value = lo if value is None else value
    if not all(map(_real, (lo, hi, step, value))) or not lo <= value <= hi or step <= 0:
        raise ValueError(f"slider needs finite numbers lo <= value <= hi and step > 0, got {(lo, hi, step, value)}")
    return Knob("slider", value, (lo, hi, step), label)


def choice(options: list | tuple | dict, value: Any = None, *, label: str | None = None) -> Knob:
    """One of ``options`` (a list, or a dict label -> value); default ``value`` (None: the first)."""
    pairs = tuple(options.items()) if isinstance(options, dict) else tuple((str(v), v) for v in options)
    if not pairs or (value is not None and not any(v is value or v == value for _, v in pairs)):
        raise ValueError(f"choice needs a non-empty list of options that holds value {value!r}, got {options!r}")
    return Knob("choice", pairs[0][1] if value is None else value, pairs, label)


def toggle(value: bool = False, *, label: str | None = None) -> Knob:
    """An on/off check box; default ``value``."""
    if not isinstance(value, bool):
        raise ValueError(f"toggle needs True or False, got {value!r}")
    return Knob("toggle", value, (), label)


def _widget(name: str, knob: Knob):
    """The ipywidget of a knob (a choice's widget value is the option's index)."""
    import ipywidgets as w
    common = {"description": knob.label or name, "style": {"description_width": "initial"}}
    if knob.kind == "toggle":
        return w.Checkbox(value=knob.value, indent=False, **common)
    if knob.kind == "slider":
        lo, hi, step = knob.options
        if all(isinstance(v, numbers.Integral) for v in (lo, hi, step, knob.value)):
            return w.IntSlider(min=lo, max=hi, step=step, value=knob.value, **common)
        digits = max(0, -decimal.Decimal(str(step)).as_tuple().exponent)   # 0.25 -> 2: shows every step
        return w.FloatSlider(min=lo, max=hi, step=step, value=knob.value, readout_format=f".{digits}f", **common)
    index = next(i for i, (_, v) in enumerate(knob.options) if v is knob.value or v == knob.value)
    kind = w.SelectionSlider if all(_real(v) for _, v in knob.options) else w.Dropdown
    return kind(options=[(label, i) for i, (label, _) in enumerate(knob.options)], value=index, **common)


class Exploration:
    """One exploration: ``figure``, the current ``values``, ``seconds`` of the last redraw (draw and PNG),
    ``redraws`` (the live ones, counted under the knobs), ``widgets`` (name -> ipywidget, "_box" holds them all;
    empty until shown) and ``error`` (of the last live redraw, or None)."""

    def __init__(self, draw: Callable, knobs: dict[str, Knob], figsize: tuple | None = None) -> None:
        self.draw, self.knobs = draw, knobs
        self.values = {name: knob.value for name, knob in knobs.items()}
        self.figure = Figure(figsize=figsize)
        self.widgets: dict = {}
        self.seconds, self.error, self.redraws, self._handle, self._status = math.nan, None, 0, None, None
        self._crop = None

    def redraw(self, **changes: Any) -> float:
        """Set the values named in ``changes``, clear and redraw the figure, refresh its display; returns seconds."""
        if set(changes) - set(self.values):
            raise ValueError(f"no knob named {sorted(set(changes) - set(self.values))}; knobs: {list(self.values)}")
        self.values.update(changes)
        t0 = time.perf_counter()
        self.figure.clear()
        self.draw(self.figure, **self.values)
        bundle = self.bundle()
        self.seconds = time.perf_counter() - t0
        if self._handle is not None:
            self._handle.update(bundle, raw=True)
        return self.seconds

    def bundle(self) -> dict:
        """The figure as a display bundle: a PNG at the figure's dpi (as shown inline) and matplotlib's repr. The
        PNG is cropped to the first draw's tight box plus a margin, kept for every redraw: the image does not
        jump while a knob moves, and a redraw costs one rendering instead of the two of a tight crop."""
        if self._crop is None:
            tight = self.figure.get_tightbbox().padded(CROP_MARGIN)
            self._crop = Bbox.intersection(tight, self.figure.bbox_inches) or self.figure.bbox_inches
        buf = io.BytesIO()
        self.figure.savefig(buf, format="png", dpi=self.figure.dpi, bbox_inches=self._crop)
        return {"image/png": base64.b64encode(buf.getvalue()).decode("ascii"), "text/plain": repr(self.figure)}

    def _on_change(self, name: str, change: dict) -> None:
        knob = self.knobs[name]
        value = knob.options[change["new"]][1] if knob.kind == "choice" else change["new"]
        try:
            self.redraw(**{name: value})
            self.redraws += 1
            self.error, text = None, f"redraw {self.redraws}: {1000 * self.seconds:.0f} ms"
        except Exception as exc:  # a live redraw reports its error here, not in the kernel's log
            self.error = text = f"{type(exc).__name__}: {exc}"
        self._status.value = f"<small>{html.escape(text)}</small>"

    def show(self) -> None:
        """Display the knobs (text alone without ipywidgets) and the figure; a knob's change redraws."""
        from IPython.display import display
        text = "knobs: " + ", ".join(f"{name}={value!r}" for name, value in self.values.items())
        try:
            import ipywidgets as w
        except ImportError:
            display({"text/plain": text + " (ipywidgets is not installed: no sliders)"}, raw=True)
        else:
            self.widgets = {name: _widget(name, knob) for name, knob in self.knobs.items()}
            for name, widget in self.widgets.items():
                widget.observe(lambda change, name=name: self._on_change(name, change), names="value")
            self._status = w.HTML(value="", layout={"min_height": "1.5em"})   # no jump at the first redraw
            self.widgets["_box"] = box = w.VBox([*self.widgets.values(), self._status])
            view = {"version_major": 2, "version_minor": 0, "model_id": box.model_id}
            display({"text/plain": text, "application/vnd.jupyter.widget-view+json": view}, raw=True)
        self._handle = display(self.bundle(), raw=True, display_id=True)

    def _ipython_display_(self) -> None:
        """Nothing: explore() has shown the knobs and the figure (a cell ending in explore(...) adds no output)."""

    def close(self) -> None:
        """Close the widgets (with their layout and style models) and empty the figure."""
        for widget in [*self.widgets.values(), self._status]:
            for model in (widget, getattr(widget, "layout", None), getattr(widget, "style", None)):
                if model is not None:
                    model.close()
        self.widgets, self._handle, self._status = {}, None, None
        self.figure.clear()


_OPEN: dict[tuple, Exploration] = {}


def explore(draw: Callable, /, figsize: tuple[float, float] | None = None, **knobs: Any) -> Exploration:
    """Draw ``draw(fig, **values)`` at the knobs' defaults and, in IPython, show the knobs and the figure.

    ``knobs``: name -> slider(...), choice(...) or toggle(...). ``draw`` draws on the ``fig`` it is given, never
    on pyplot's. An error of the first draw propagates; a live redraw's is shown under the knobs, and the figure
    keeps its last good image.
    """
    function(draw, "draw")
    if not knobs:
        raise ValueError("explore needs at least one knob, e.g. explore(draw, sigma=slider(0.0, 3.0, 0.5, 1.0))")
    bad = [name for name, knob in knobs.items() if not isinstance(knob, Knob)]
    if bad:
        raise ValueError(f"knobs {bad} must each be a slider(...), choice(...) or toggle(...)")
    key = (getattr(draw, "__module__", None), getattr(draw, "__qualname__", None), tuple(knobs))
    if key in _OPEN:
        _OPEN.pop(key).close()
    ex = Exploration(draw, knobs, figsize)
    plt = sys.modules.get("matplotlib.pyplot")
    before = set(plt.get_fignums()) if plt else set()
    ex.redraw()
    opened = sorted(set(plt.get_fignums()) - before) if plt else []
    if opened:
        for num in opened:
            plt.close(num)
        raise ValueError(f"draw opened pyplot figure(s) {opened}: draw on the fig it is given (fig.subplots())")
    try:
        from IPython import get_ipython
    except ImportError:
        return ex
    if get_ipython() is not None:
        ex.show()
        _OPEN[key] = ex
    return ex
