"""helpers.drivebot.plotting: wrapped-angle lines broken at the wraps."""
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from helpers.drivebot.plotting import plot_wrapped_angle  # noqa: E402


def _broken(t, angle, period=360.0):
    """(t, angle) of the line plot_wrapped_angle draws."""
    fig, ax = plt.subplots()
    try:
        (line,) = plot_wrapped_angle(ax, t, angle, period)
        return np.asarray(line.get_xdata(), dtype=float), np.asarray(line.get_ydata(), dtype=float)
    finally:
        plt.close(fig)


def test_the_line_is_broken_only_at_wraps():
    t = np.arange(6.0)
    a = np.array([170.0, 175.0, 179.0, -179.0, -175.0, -170.0])
    tb, ab = _broken(t, a)
    assert tb.size == ab.size == 7
    assert np.isnan(ab[3]) and np.isnan(tb[3])
    assert np.array_equal(ab[~np.isnan(ab)], a) and np.array_equal(tb[~np.isnan(tb)], t)


def test_radians_and_no_wrap():
    t = np.linspace(0.0, 1.0, 5)
    a = np.array([3.0, 3.1, -3.1, -3.0, 3.1])
    _, ab = _broken(t, a, period=2 * math.pi)
    assert np.sum(np.isnan(ab)) == 2
    smooth = np.linspace(-100.0, 100.0, 50)  # large total change, small steps: no break
    tb, ab = _broken(np.arange(50.0), smooth)
    assert not np.any(np.isnan(ab)) and tb.size == 50


@pytest.mark.parametrize("args, match", [
    ((np.arange(3.0), np.arange(4.0)), "same length"),
    ((np.arange(3.0), np.arange(3.0), 0.0), "period"),
    ((np.arange(3.0), np.arange(3.0), True), "period"),
])
def test_bad_input(args, match):
    with pytest.raises(ValueError, match=match):
        _broken(*args)


def test_plot_wrapped_angle_passes_its_keywords_on():
    fig, ax = plt.subplots()
    (line,) = plot_wrapped_angle(ax, [0.0, 1.0, 2.0], [179.0, -179.0, -178.0], label="psi")
    y = line.get_ydata()
    assert len(y) == 4 and np.isnan(y[1]) and line.get_label() == "psi"
    plt.close(fig)
