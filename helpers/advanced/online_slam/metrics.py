"""Scoring an online association against a truth the front-end never saw.

Every observation o has a true source t(o) (a landmark id; 0 for clutter) and, at the end of the run, an
assignment a(o): the landmark of the map it is an edge to, or −1 (discarded, or its tentative landmark was dropped
or never confirmed). The found landmarks have their own numbering, so they are first matched to the true ones:

    **best one-to-one matching**: the pairing of found landmarks f and true landmarks t that maximises the number
    of observations assigned to f whose source is t (the Hungarian algorithm on the contingency table; a found
    landmark made only of clutter, or a duplicate, stays unmatched).

Then, with π the matching,

    correct(o)  = a(o) ≥ 0 and π(a(o)) = t(o) ≠ 0
    precision   = #correct / #{o : a(o) ≥ 0}            (pairings in the map that are right)
    recall      = #correct / #{o : t(o) ≠ 0}            (true detections that ended up right in the map)
    agreement   = #correct / #{o}                       (Victoria Park: every observation has a source)

Each ratio is NaN when its denominator is 0 (nothing paired: precision undefined). The map error is the distance
between each matched found landmark's estimate and its true position.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from ...validation import int_array

__all__ = ["best_matching", "association_scores", "map_errors"]


def best_matching(assigned, truth) -> dict:
    """{found landmark: true landmark} maximising the observations they share (module docstring).

    ``assigned`` (N,) found landmark per observation (−1: none); ``truth`` (N,) true source (0: clutter).
    Only pairs sharing at least one observation are matched.
    """
    assigned = int_array(assigned, "assigned")
    truth = int_array(truth, "truth")
    if assigned.shape != truth.shape:
        raise ValueError(f"assigned and truth must have the same length, got {assigned.size} and {truth.size}")
    ok = (assigned >= 0) & (truth != 0)
    if not ok.any():
        return {}
    found, fi = np.unique(assigned[ok], return_inverse=True)
    true, ti = np.unique(truth[ok], return_inverse=True)
    counts = np.zeros((found.size, true.size))
    np.add.at(counts, (fi, ti), 1.0)
    rows, cols = linear_sum_assignment(-counts)
    return {int(found[r]): int(true[c]) for r, c in zip(rows, cols) if counts[r, c] > 0}


def association_scores(assigned, truth) -> dict:
    """precision, recall, agreement, counts and the matching (module docstring) of one run."""
    assigned = int_array(assigned, "assigned")
    truth = int_array(truth, "truth")
    matching = best_matching(assigned, truth)
    mapped = np.array([matching.get(int(a), -1) if a >= 0 else -1 for a in assigned], dtype=np.int64)
    correct = (assigned >= 0) & (truth != 0) & (mapped == truth)
    n_pairings = int(np.count_nonzero(assigned >= 0))
    n_true = int(np.count_nonzero(truth != 0))
    n_found = int(np.unique(assigned[assigned >= 0]).size)
    return {
        "precision": float(correct.sum() / n_pairings) if n_pairings else float("nan"),
        "recall": float(correct.sum() / n_true) if n_true else float("nan"),
        "agreement": float(correct.sum() / assigned.size) if assigned.size else float("nan"),
        "n_observations": int(assigned.size),
        "n_true_detections": n_true,
        "n_clutter": int(np.count_nonzero(truth == 0)),
        "n_pairings": n_pairings,
        "n_correct": int(correct.sum()),
        "n_clutter_paired": int(np.count_nonzero((assigned >= 0) & (truth == 0))),
        "n_landmarks": n_found,
        "n_true_landmarks": int(np.unique(truth[truth != 0]).size),
        "n_matched": len(matching),
        "matching": matching,
    }


def map_errors(matching: dict, found_positions: dict, true_positions: dict) -> np.ndarray:
    """‖found − true‖ for every matched pair (in the matching's order)."""
    return np.array([float(np.linalg.norm(np.asarray(found_positions[f]) - np.asarray(true_positions[t])))
                     for f, t in matching.items()])
