"""helpers.explore: the knobs, the redraw, what a cell displays (and that a headless kernel stores the same
outputs every run), live changes through the widgets, errors, and no leaked figures or widgets."""
import base64
import sys

import matplotlib

matplotlib.use("Agg")
import IPython.display
import matplotlib.pyplot as plt
import nbformat
import pytest
from nbclient import NotebookClient

from helpers import explore as ex_mod
from helpers.explore import Exploration, choice, explore, slider, toggle


def line(fig, s, colour="k", grid=True):
    ax = fig.subplots()
    ax.plot([0, s], [0, 1], color=colour)
    ax.grid(grid)


def knobs():
    return {"s": slider(0.5, 2.5, 0.25, value=1.0), "colour": choice({"black": "k", "red": "r"}),
            "grid": toggle(True)}


@pytest.fixture
def shown(monkeypatch):
    """Record what explore() displays, as if in IPython (a display id gives a handle that records updates)."""
    records = []

    class Handle:
        def update(self, obj, raw=False):
            records.append(("update", obj))

    def display(obj, raw=False, display_id=None):
        assert raw
        records.append(("display", obj))
        return Handle() if display_id else None

    monkeypatch.setattr(IPython.display, "display", display)
    monkeypatch.setattr(IPython, "get_ipython", lambda: object())
    yield records
    for ex in list(ex_mod._OPEN.values()):
        ex.close()
    ex_mod._OPEN.clear()


def test_knob_checks():
    assert slider(0, 10, 1).value == 0 and choice(["NN", "JCBB"]).value == "NN" and toggle().value is False
    assert choice({"on": 1, "off": 0}, 0).options == (("on", 1), ("off", 0))
    for bad in (lambda: slider(0, 1, 0.1, 2), lambda: slider(0, 1, 0), lambda: slider(0, float("nan"), 0.1),
                lambda: slider(True, 2, 1), lambda: choice([]), lambda: choice(["a"], "b"), lambda: toggle(1)):
        with pytest.raises(ValueError):
            bad()
    with pytest.raises(ValueError, match="must each be a slider"):
        explore(line, s=(0.5, 2.5, 0.25, 1.0))
    with pytest.raises(ValueError, match="at least one knob"):
        explore(line)
    with pytest.raises(ValueError, match="draw"):
        explore("line", s=slider(0, 1, 0.5))


def test_outside_ipython_the_figure_is_drawn_at_the_defaults_and_nothing_is_shown(monkeypatch):
    monkeypatch.setattr(IPython, "get_ipython", lambda: None)
    seen = []
    ex = explore(lambda fig, **v: (seen.append(v), line(fig, **v)), **knobs())
    assert isinstance(ex, Exploration) and seen == [{"s": 1.0, "colour": "k", "grid": True}]
    assert ex.widgets == {} and ex.seconds > 0 and len(ex.figure.axes) == 1
    ex.redraw(s=2.0)
    assert ex.values["s"] == 2.0 and len(ex.figure.axes) == 1           # cleared, then drawn again
    with pytest.raises(ValueError, match="no knob named"):
        ex.redraw(t=1)


def test_a_cell_shows_the_knobs_and_the_figure_with_text_from_the_defaults(shown):
    ex = explore(line, **knobs())
    assert [kind for kind, _ in shown] == ["display", "display"]
    controls, figure = shown[0][1], shown[1][1]
    assert controls["text/plain"] == "knobs: s=1.0, colour='k', grid=True"
    assert controls["application/vnd.jupyter.widget-view+json"]["model_id"] == ex.widgets["_box"].model_id
    assert base64.b64decode(figure["image/png"]).startswith(b"\x89PNG")
    assert figure["text/plain"].startswith("<Figure size")
    assert type(ex.widgets["s"]).__name__ == "FloatSlider" and type(ex.widgets["grid"]).__name__ == "Checkbox"
    assert type(ex.widgets["colour"]).__name__ == "Dropdown"
    numbers = explore(line, s=choice([0.5, 1.0, 2.0], value=1.0), grid=slider(0, 4, 1, value=2))
    assert type(numbers.widgets["s"]).__name__ == "SelectionSlider" and numbers.widgets["s"].value == 1
    assert type(numbers.widgets["grid"]).__name__ == "IntSlider"


def test_without_ipywidgets_the_knobs_are_text_and_the_figure_is_shown(shown, monkeypatch):
    monkeypatch.setitem(sys.modules, "ipywidgets", None)                # import ipywidgets raises ImportError
    ex = explore(line, s=slider(0.5, 2.5, 0.25, value=1.0))
    assert [obj for _, obj in shown][0] == {"text/plain": "knobs: s=1.0 (ipywidgets is not installed: no sliders)"}
    assert "image/png" in shown[1][1] and ex.widgets == {}


def test_moving_a_knob_redraws_the_same_figure_and_updates_the_display(shown):
    ex = explore(line, **knobs())
    figure, first = ex.figure, shown[1][1]["image/png"]
    ex.widgets["s"].value = 2.25
    ex.widgets["colour"].value = 1                                      # the second option: "red" -> "r"
    assert ex.values == {"s": 2.25, "colour": "r", "grid": True} and ex.figure is figure
    updates = [obj for kind, obj in shown if kind == "update"]
    assert len(updates) == 2 and updates[-1]["image/png"] != first
    size = {base64.b64decode(png["image/png"])[16:24] for png in [shown[1][1], *updates]}   # PNG width, height
    assert len(size) == 1                                               # one crop for every redraw: no jump
    assert ex.error is None and ex._status.value.startswith("<small>redraw 2: ") and ex.redraws == 2


def test_an_error_in_a_live_redraw_is_shown_under_the_knobs_and_the_image_stays(shown):
    def draw(fig, s):
        if s > 2:
            raise NotImplementedError("exercise x is not implemented yet")
        line(fig, s)

    ex = explore(draw, s=slider(0.5, 2.5, 0.25, value=1.0))
    ex.widgets["s"].value = 2.5
    assert ex.error == "NotImplementedError: exercise x is not implemented yet"
    assert "not implemented" in ex._status.value and not [k for k, _ in shown if k == "update"]
    ex.widgets["s"].value = 1.5
    assert ex.error is None and len([k for k, _ in shown if k == "update"]) == 1
    with pytest.raises(NotImplementedError):                            # the first draw's error propagates
        explore(draw, s=slider(0.5, 2.5, 0.25, value=2.5))


def test_running_the_cell_again_closes_the_previous_exploration(shown):
    from ipywidgets.widgets.widget import _instances                    # every open widget model
    first = explore(line, **knobs())
    widgets, models = list(first.widgets.values()), len(_instances)
    second = explore(line, **knobs())
    assert all(w.comm is None for w in widgets) and first.widgets == {} and not first.figure.axes
    assert list(ex_mod._OPEN.values()) == [second] and second.widgets["s"].comm is not None
    for _ in range(3):
        explore(line, **knobs())
    assert len(_instances) == models                                    # no widget model left behind


def test_a_draw_that_opens_a_pyplot_figure_is_refused_and_the_figure_closed():
    before = plt.get_fignums()

    def draw(fig, s):
        plt.subplots()

    with pytest.raises(ValueError, match="draw on the fig it is given"):
        explore(draw, s=slider(0, 1, 0.5))
    assert plt.get_fignums() == before


def test_a_headless_kernel_stores_the_two_outputs_with_the_same_text_every_run(tmp_path):
    """What nbval compares (everything but image/png and the widget view) is the same in two runs."""
    source = ("from helpers.explore import explore, slider\n"
              "def draw(fig, s):\n    fig.subplots().plot([0, s], [0, 1])\n"
              "explore(draw, s=slider(0.5, 2.5, 0.25, value=1.0))")
    runs = []
    for _ in range(2):
        nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(source)])
        NotebookClient(nb, timeout=120, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}},
                       extra_arguments=["--IPKernelApp.log_level=ERROR"]).execute()
        runs.append(nb.cells[0].outputs)
    for outputs in runs:
        assert [o.output_type for o in outputs] == ["display_data", "display_data"]
        assert outputs[0].data["text/plain"] == "knobs: s=1.0" and "image/png" in outputs[1].data
    compared = [[{k: v for k, v in o.data.items() if k not in ("image/png", "application/vnd.jupyter.widget-view+json")}
                 for o in outputs] for outputs in runs]
    assert compared[0] == compared[1]
