"""Precision/recall that are undefined (NaN, "n/a") when nothing was paired, and their plot."""
import numpy as np
import pytest

from helpers.association.evaluation import fmt_rate, rates, run_trials
from helpers.association.maximum_likelihood import maximum_likelihood
from helpers.association.plots import plot_rates


def test_no_pairing_gives_undefined_precision():
    res = run_trials({"none": lambda D, Y: maximum_likelihood(D, Y, alpha=1e6),
                      "gate": maximum_likelihood}, 3, seed=0, n_landmarks=30, n_visible=5)
    r = rates(res, "none")
    assert r["n_pred"] == 0 and np.isnan(r["precision"]) and r["recall"] == 0.0
    g = rates(res, "gate")
    assert g["n_pred"] > 0 and 0.0 <= g["precision"] <= 1.0
    assert g["precision"] == pytest.approx(res.summary()["gate"]["precision"])
    with pytest.raises(ValueError, match="name"):
        rates(res, "missing")


def test_fmt_rate():
    assert fmt_rate(0.5) == "0.500" and fmt_rate(float("nan")) == "  n/a"
    with pytest.raises(ValueError, match="digits"):
        fmt_rate(0.5, digits=-1)


def test_plot_rates_shades_the_undefined_range():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    span = plot_rates(ax, [1e-3, 1e-2, 1e-1, 1.0], [0.7, 0.8, np.nan, np.nan], [0.8, 0.7, 0.0, 0.0])
    assert span is not None and 1e-2 < span[0] < 1e-1 and span[1] == 1.0
    assert plot_rates(ax, [1.0, 2.0], [0.5, 0.6], [0.5, 0.4], logx=False) is None
    with pytest.raises(ValueError, match="same length"):
        plot_rates(ax, [1.0], [0.5, 0.6], [0.5])
    plt.close(fig)
