"""One redraw of the Lab 8 exploration: SNN on an image for a given state, drawn with its verdicts.

    draw_snn(fig, image, camera, features, state, n_sigma, enforce_joint_compatibility, true_pixels)

runs :func:`~helpers.association.lab_demo.association_demo` on the precomputed ``features`` (the detector is the
slow part and does not change with a knob), draws Figure 1 (:func:`~helpers.association.lab_demo.plot_association`)
with the true pixels, and titles it with the verdict counts (:func:`~helpers.association.lab_demo.verdicts`). A
notebook wraps it in a ``draw(fig, **knobs)`` for :func:`helpers.explore.explore`, building the state from the
knobs (a pose error in σ, say).
"""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from ..camera import Camera
from ..features import Features
from ..gaussian import Gaussian
from ..state_slam import StateSLAM
from .lab_demo import AssociationResult, association_demo, figure1_legend_handles, plot_association, verdicts

__all__ = ["draw_snn", "VERDICTS"]

#: the verdicts counted in the title, in this order
VERDICTS = ("correct", "correct null", "missed", "wrong")


def draw_snn(fig: Figure, image: np.ndarray, camera: Camera, features: Features, state: StateSLAM,
             n_sigma: float = 3.0, enforce_joint_compatibility: bool = False, true_pixels: ArrayLike | None = None,
             noise: Gaussian | None = None, image_scale: float = 0.5, window: ArrayLike | None = None,
             label: str = "") -> tuple[AssociationResult, dict]:
    """Draw SNN's association of ``state``'s landmarks with ``features`` on ``fig`` (one axes, Figure 1's
    conventions, the legend below). With ``true_pixels`` (2, n_L) the verdicts are drawn and counted in the title
    (tolerance 2 px). Returns (the association, {verdict: count}; empty without ``true_pixels``)."""
    if not isinstance(fig, Figure):
        raise ValueError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
    result = association_demo(image, camera, state, features=features, n_sigma=n_sigma, verbose=False,
                              enforce_joint_compatibility=enforce_joint_compatibility, noise=noise)
    rows = None if true_pixels is None else verdicts(result, true_pixels)
    counts = {} if rows is None else {v: sum(r["verdict"] == v for r in rows) for v in VERDICTS}
    ax = fig.subplots()
    plot_association(image, result, ax=ax, n_sigma=n_sigma, truth=rows, legend=False, image_scale=image_scale,
                     window=window)
    tally = ", ".join(f"{n} {v}" for v, n in counts.items() if n) if counts else \
        f"{result.n_associated} of {result.idx_landmarks.size} associated"
    ax.set_title(f"{label + ': ' if label else ''}SNN{' + JC' if enforce_joint_compatibility else ''}, "
                 f"{n_sigma:g}σ gate — {tally}", fontsize=10)
    fig.legend(handles=figure1_legend_handles(rows is not None), loc="lower center", ncol=2, fontsize=7.5,
               frameon=False)
    fig.subplots_adjust(bottom=0.2, top=0.93)
    return result, counts
