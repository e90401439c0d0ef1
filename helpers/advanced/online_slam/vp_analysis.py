"""Victoria Park, looked at after the run: the trajectories and maps of two runs, the trees an online run mapped
twice, and how far the file's odometry drifts from the known-id solution (notebook 23).

    ref = res.reference                     # the known-id run (run_victoria_park(..., known_id_reference=True))
    drift = odometry_drift(ref, lengths=(10, 50, 200, 800))
    twice = duplicate_landmarks(res)        # trees the online run mapped twice, and after how many steps

``odometry_drift`` compares the file's odometry, composed over n consecutive steps, with the relative pose of the
known-id solution between the same two poses: the heading error e_θ = θ_sol − θ_odo (wrapped), the position error
|p_sol − p_odo| in the first pose's frame, and the normalised error eᵀ P⁻¹ e with P the odometry's own covariance
propagated over the n steps (P ← J₁ P J₁ᵀ + J₂ Q J₂ᵀ, the Jacobians of the pose composition). For odometry whose
covariance describes its errors, eᵀ P⁻¹ e is χ²₃-distributed whatever n is (mean 3, median 2.37).
"""
from __future__ import annotations

import math

import numpy as np

from ...datasets import read_dataset
from ...graph import VertexPointXY, VertexSE2
from ...validation import integer
from .victoria_park import victoria_park_scans

__all__ = ["poses", "landmark_positions", "odometry_drift", "plot_map", "duplicate_landmarks"]


def poses(res) -> np.ndarray:
    """(N, 3) pose estimates of a run's graph, in the order the poses were created (file order)."""
    return np.array([v.estimate for v in res.graph.vertices() if isinstance(v, VertexSE2)])


def landmark_positions(res) -> np.ndarray:
    """(L, 2) landmark estimates: the file's landmarks for a known-id run, the confirmed ones for an online run."""
    if res.frontend is None:
        pts = [v.estimate for v in res.landmark_vertices.values()]
    else:
        pts = [t.vertex.estimate for t in res.frontend.confirmed_tracks()]
    if not pts:                      # a run that confirmed nothing
        pts = [v.estimate for v in res.graph.vertices() if isinstance(v, VertexPointXY)]
    return np.array(pts, dtype=float).reshape(-1, 2)


def _odometry(stream):
    return [(item[3], np.linalg.inv(item[4])) for item in stream if item[0] == "odometry"]


def _compose_with_covariance(odo, start, n):
    """The odometry composed over steps start … start+n−1 from the identity, and its propagated covariance."""
    p, P = np.zeros(3), np.zeros((3, 3))
    for z, Q in odo[start:start + n]:
        c, s = math.cos(p[2]), math.sin(p[2])
        J1 = np.array([[1.0, 0.0, -s * z[0] - c * z[1]], [0.0, 1.0, c * z[0] - s * z[1]], [0.0, 0.0, 1.0]])
        J2 = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        P = J1 @ P @ J1.T + J2 @ Q @ J2.T
        p = np.array([p[0] + c * z[0] - s * z[1], p[1] + s * z[0] + c * z[1], p[2] + z[2]])
    return p, P


def _relative(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    d = b[:2] - a[:2]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], b[2] - a[2]])


def odometry_drift(reference, lengths=(10, 50, 200, 800), n_samples: int = 100, seed: int = 0) -> list[dict]:
    """Per length n: the odometry over n steps against the known-id solution ``reference`` (module docstring), at
    ``n_samples`` start poses drawn with a seeded Generator. Each row: n, path (median metres driven),
    heading_error (median |e_θ|, rad), heading_bias (mean e_θ, rad), heading_sigma (median odometry σ_θ, rad),
    position_error (median, m), nees (median eᵀP⁻¹e)."""
    n_samples = integer(n_samples, "n_samples", minimum=1)
    odo = _odometry(victoria_park_scans(read_dataset("victoria_park")))
    X = poses(reference)
    if X.shape[0] != len(odo) + 1:
        raise ValueError(f"reference: expected a Victoria Park graph of {len(odo) + 1} poses, got {X.shape[0]}")
    rng = np.random.default_rng(integer(seed, "seed", minimum=0))
    rows = []
    for n in (integer(v, "lengths", minimum=1, below=len(odo)) for v in lengths):
        he, hs, pe, nees, path = [], [], [], [], []
        for i in rng.integers(0, len(odo) - n, n_samples):
            p, P = _compose_with_covariance(odo, int(i), n)
            e = _relative(X[i], X[i + n]) - p
            e[2] = math.remainder(e[2], 2.0 * math.pi)
            he.append(e[2])
            hs.append(math.sqrt(P[2, 2]))
            pe.append(math.hypot(e[0], e[1]))
            nees.append(float(e @ np.linalg.solve(P, e)))
            path.append(sum(math.hypot(z[0], z[1]) for z, _ in odo[int(i):int(i) + n]))
        he = np.array(he)
        rows.append({"n": n, "path": float(np.median(path)), "heading_error": float(np.median(np.abs(he))),
                     "heading_bias": float(he.mean()), "heading_sigma": float(np.median(hs)),
                     "position_error": float(np.median(pe)), "nees": float(np.median(nees))})
    return rows


def plot_map(ax, online, reference, colors) -> None:
    """Trajectories and landmarks of the online run and the known-id reference on one axes (metres)."""
    Xr, Xo = poses(reference), poses(online)
    Lr, Lo = landmark_positions(reference), landmark_positions(online)
    ax.plot(Xr[:, 0], Xr[:, 1], color=colors["muted"], lw=0.8, label="trajectory, ids known")
    ax.plot(Xo[:, 0], Xo[:, 1], color=colors["alt"], lw=0.8, alpha=0.8, label="trajectory, ids hidden")
    ax.plot(Lr[:, 0], Lr[:, 1], "x", color=colors["truth"], ms=5, label=f"landmarks, ids known ({len(Lr)})")
    ax.plot(Lo[:, 0], Lo[:, 1], "o", mfc="none", color=colors["alt"], ms=4,
            label=f"landmarks found, ids hidden ({len(Lo)})")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    ax.legend(loc="best", fontsize="small")


def _majority(ids) -> int:
    values, counts = np.unique(np.asarray(ids, dtype=np.int64), return_counts=True)
    return int(values[np.argmax(counts)]) if values.size else 0


def _observation_steps() -> np.ndarray:
    """The number of odometry steps before each observation of the file (file order)."""
    steps, out = 0, []
    for item in victoria_park_scans(read_dataset("victoria_park")):
        if item[0] == "odometry":
            steps += 1
        else:
            out.extend([steps] * item[2].shape[1])
    return np.array(out, dtype=np.int64)


def duplicate_landmarks(res, steps=None) -> list[dict]:
    """Trees mapped twice, after the fact: every confirmed landmark of an online run whose majority file id is the
    majority id of a landmark confirmed before it. One row per duplicate, in the order of confirmation: key, id,
    first (the earlier landmark's key), gap (odometry steps from the last observation of that id on the earlier
    landmark to the first observation on this one; −1 when the earlier landmark has none before it). ``steps``:
    the odometry steps before each observation (default: Victoria Park's, in file order)."""
    fe = getattr(res, "frontend", None)
    if fe is None:
        raise ValueError("res: an online run (run_victoria_park with data_association set) is needed")
    assigned, truth = fe.observation_assignment(), np.asarray(res.truth)
    steps = _observation_steps() if steps is None else np.asarray(steps)
    if steps.shape != truth.shape:
        raise ValueError(f"steps: expected one per observation ({truth.size}), got shape {steps.shape}")
    owner, rows = {}, []
    for t in sorted(fe.confirmed_tracks(), key=lambda t: (t.end, t.key)):
        mine = np.flatnonzero(assigned == t.key)
        if not mine.size:
            continue
        lid = _majority(truth[mine])
        if lid not in owner:
            owner[lid] = t
            continue
        first = owner[lid]
        start = mine[0]
        before = np.flatnonzero((assigned == first.key) & (truth == lid))
        before = before[before < start]
        gap = int(steps[start] - steps[before.max()]) if before.size else -1
        rows.append({"key": t.key, "id": lid, "first": first.key, "gap": gap})
    return rows
