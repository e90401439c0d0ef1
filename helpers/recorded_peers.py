"""Peer results recorded from GTSAM and g2o, so that notebooks show them whether or not the peers are installed.

``benchmarks/record_peers.py`` runs the pinned peer versions (``environment-peers.txt``) and stores the numbers in
``data/peer_results.json`` and the Victoria Park state with GTSAM's pose covariances in
``data/peer_victoria_park.npz``; ``tests/test_recorded_peers.py`` re-runs the peers where installed. JSON layout::

    recorded_with: {command, date, gtsam, g2opy, numpy, python, machine}
    <dataset>:     {<solver>: {solver, config, iterations, chi2, chi2_history, time_s, marginals_time_s}}
    convergence:   {recorded_with: {...}, <dataset>: {<run>: {the same fields}}}   (every dataset of DATASETS)

``convergence`` holds GTSAM's LM on every shipped dataset: "GTSAM" (default parameters) and "GTSAM optimum"
(tolerances 1e−15; for W20000 "GTSAM 200 iterations"). χ² values are Σ eᵀΩe (GTSAM's error × 2); times are wall
seconds on the recording machine.
"""
from __future__ import annotations

import json

import numpy as np

from .paths import data_path

__all__ = ["RESULTS_FILE", "STATE_FILE", "CONVERGENCE", "load_recorded_peers", "recorded_convergence",
           "load_victoria_park_marginals", "covariance_agreement"]

RESULTS_FILE = "peer_results.json"
CONVERGENCE = "convergence"
STATE_FILE = "peer_victoria_park.npz"


def load_recorded_peers() -> dict:
    """The recorded peer results (``data/peer_results.json``) as a dict."""
    path = data_path(RESULTS_FILE)
    if not path.is_file():
        raise FileNotFoundError(f"{path} is missing; record it with `python benchmarks/record_peers.py`")
    return json.loads(path.read_text(encoding="utf-8"))


def recorded_convergence(name: str, run: str = "GTSAM optimum") -> dict:
    """GTSAM's recorded run ``run`` ("GTSAM", "GTSAM optimum", or for W20000 "GTSAM 200 iterations") on the shipped
    dataset ``name``: {solver, config, iterations, chi2, chi2_history, time_s, marginals_time_s}.

    Raises KeyError naming the dataset and the runs recorded for it when there is no such run."""
    part = load_recorded_peers().get(CONVERGENCE, {})
    runs = part.get(name)
    if runs is None or name == "recorded_with":
        raise KeyError(f"no convergence run recorded for dataset {name!r}; recorded: "
                       f"{sorted(k for k in part if k != 'recorded_with')}")
    if run not in runs:
        raise KeyError(f"no run {run!r} recorded for dataset {name!r}; recorded: {sorted(runs)}")
    return runs[run]


def load_victoria_park_marginals() -> dict:
    """The Victoria Park state and GTSAM's pose covariances there (``data/peer_victoria_park.npz``).

    Keys: ``pose_ids`` (N,), ``poses`` (N, 3) [x, y, ψ], ``point_ids`` (M,), ``points`` (M, 2), ``cov_pose_ids`` (K,)
    and ``gtsam_cov`` (K, 3, 3): GTSAM's ``Marginals`` at that state, rotated to the world-frame (x, y, ψ)
    coordinates of ``VertexSE2`` (Σ_w = M Σ_body Mᵀ, M = blockdiag(R(ψ), 1)).
    """
    with np.load(data_path(STATE_FILE)) as npz:
        return {key: npz[key] for key in npz.files}


def covariance_agreement(ours: dict, reference: dict) -> float:
    """max over the reference's keys of ‖Σ_ours − Σ_ref‖_F / ‖Σ_ref‖_F (zero or fixed blocks skipped).

    ``ours`` and ``reference`` map a pose id to its 3×3 covariance. Raises ValueError when no pose is shared.
    """
    worst, compared = 0.0, 0
    for key, ref in reference.items():
        mine = ours.get(key)
        if mine is None or not np.any(mine) or np.linalg.norm(ref) < 1e-9:
            continue
        worst = max(worst, float(np.linalg.norm(np.asarray(mine) - ref) / np.linalg.norm(ref)))
        compared += 1
    if compared == 0:
        raise ValueError("ours and reference share no pose with a non-zero covariance")
    return worst
