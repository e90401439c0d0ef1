"""Landmarks as the front-end sees them: tentative until confirmed, and the rules that decide.

Lecture L09: "new landmarks need confirmation over several observations". An observation that the association
leaves unpaired starts a **tentative** landmark. It is not in the graph: its observations wait in the track
(pose vertex, measurement). Each later scan offers it to the association like any other candidate:

- re-observed (paired) → one more hit; at ``n_confirm`` hits it is **confirmed**: its vertex enters the graph,
  initialised by the inverse observation of its first sighting (as a known-id system does), together with an
  edge for every observation it collected;
- predicted inside the sensor footprint but not paired in ``n_miss`` consecutive such scans → **dropped**
  (a landmark that is really there is seen again while the sensor is near it; clutter is not);
- still tentative ``max_age`` scans after its birth → dropped (None: no limit) — this also clears tentative
  landmarks that left the footprint unconfirmed (clutter near the edge of the range, a landmark glimpsed once);
- an unpaired observation inside the exclusion gate of a (trusted) candidate — d² ≤ χ²_d at ``exclusion_n_sigma``,
  wider than the pairing gate — starts nothing: it is too close to a known landmark to be a new one, and too
  doubtful to be paired (it is discarded). None: no exclusion.

``n_confirm = 1`` confirms at the first sighting (no confirmation: every unpaired observation is a landmark).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...validation import integer, positive_number

__all__ = ["ConfirmationRules", "Track", "TENTATIVE", "CONFIRMED", "DROPPED"]

TENTATIVE, CONFIRMED, DROPPED = "tentative", "confirmed", "dropped"


@dataclass(frozen=True)
class ConfirmationRules:
    """The confirmation rule's parameters (module docstring); ValueError naming the field on bad values."""

    n_confirm: int = 3
    n_miss: int = 3
    max_age: int | None = 10
    exclusion_n_sigma: float | None = 4.0

    def __post_init__(self):
        integer(self.n_confirm, "n_confirm", minimum=1)
        integer(self.n_miss, "n_miss", minimum=1)
        integer(self.max_age, "max_age", minimum=1, allow_none=True)
        if self.exclusion_n_sigma is not None:
            positive_number(self.exclusion_n_sigma, "exclusion_n_sigma")


@dataclass
class Track:
    """One landmark of the front-end.

    key          its number (creation order, from 0)
    status       TENTATIVE, CONFIRMED or DROPPED
    birth        scan index of its first observation
    parent, z0, R0   the pose vertex, measurement and noise covariance of the first observation
    pending      [(pose vertex, z, information, observation number)] waiting for confirmation
    observations observation numbers (front-end log) paired with it, in order
    hits, misses as in the module docstring;  vertex: its graph vertex once confirmed;  end: scan of the decision
    alias_of     key of the old landmark it was merged into at a loop closure (−1: none); its observations are
                 edges to that landmark's vertex
    postponed_since  scan from which its confirmation waits for a loop-closure decision (−1: not waiting)
    """

    key: int
    birth: int
    parent: object
    z0: np.ndarray
    R0: np.ndarray
    status: str = TENTATIVE
    pending: list = field(default_factory=list)
    observations: list = field(default_factory=list)
    hits: int = 1
    misses: int = 0
    vertex: object = None
    end: int = -1
    alias_of: int = -1
    postponed_since: int = -1
