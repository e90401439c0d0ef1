"""Victoria Park, looked at after the run: trajectories and maps of two runs, and why the odometry misleads the
association (notebook support for ``run_victoria_park``).

    ref = res.reference                                  # the known-id run (run_victoria_park(..., known_id_reference=True))
    drift = odometry_drift(ref, lengths=(10, 50, 200, 800))
    pairs = near_duplicate_ids(ref, radius=2.0)
    bound = known_id_nearest_neighbour(periods=(100, 20))  # association with every past id known

``odometry_drift`` compares the file's odometry, composed over n consecutive steps, with the relative pose of the
known-id solution between the same two poses: the heading error e_θ = θ_sol − θ_odo (wrapped), the position error
|p_sol − p_odo| in the first pose's frame, and the normalised error eᵀ P⁻¹ e with P the odometry's own covariance
propagated over the n steps (P ← J₁ P J₁ᵀ + J₂ Q J₂ᵀ, the Jacobians of the pose composition). For consistent
odometry eᵀ P⁻¹ e has mean 3 (χ²₃) whatever n is.
"""
from __future__ import annotations

import math

import numpy as np

from ...datasets import read_dataset
from ...graph import VertexPointXY, VertexSE2
from ...validation import int_array, integer, positive_number
from .victoria_park import run_victoria_park, victoria_park_scans

__all__ = ["poses", "landmark_positions", "odometry_drift", "near_duplicate_ids", "known_id_nearest_neighbour",
           "smoothed_nearest_neighbour", "plot_map", "merge_outcomes",
           "duplicate_landmarks", "joined_ids"]


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


def near_duplicate_ids(reference, radius: float = 2.0) -> list[tuple]:
    """Pairs of the file's landmark ids whose known-id estimates lie within ``radius`` metres of each other:
    (id_a, id_b, distance m, co-observed: whether one scan ever saw both, observations of a, of b)."""
    radius = positive_number(radius, "radius")
    pos = reference.landmark_vertices
    if not pos:
        raise ValueError("reference: a known-id run (run_victoria_park(None) or res.reference) is needed")
    together, count = set(), {}
    for item in victoria_park_scans(read_dataset("victoria_park")):
        if item[0] == "scan":
            ids = item[4].tolist()
            for a in ids:
                count[a] = count.get(a, 0) + 1
                together.update((a, b) for b in ids if b != a)
    keys = sorted(pos)
    out = []
    for k, a in enumerate(keys):
        for b in keys[k + 1:]:
            d = float(np.linalg.norm(pos[a].estimate - pos[b].estimate))
            if d < radius:
                out.append((a, b, d, (a, b) in together, count.get(a, 0), count.get(b, 0)))
    return out


def joined_ids(truth, pairs) -> np.ndarray:
    """``truth`` (file ids) with the ids of every pair in ``pairs`` joined: each group of ids linked by the pairs
    (a, b, …) — for example the never-co-observed rows of ``near_duplicate_ids`` — is relabelled to its smallest
    id. Scoring a run against it counts one trunk labelled with two ids as one landmark."""
    truth = int_array(truth, "truth")
    parent = {}

    def root(a):
        while parent.get(a, a) != a:
            a = parent[a]
        return a

    for k, pair in enumerate(pairs):
        if len(pair) < 2:
            raise ValueError(f"pairs[{k}] must start with two ids (a, b, ...), got {pair!r}")
        a, b = root(int(pair[0])), root(int(pair[1]))
        parent[max(a, b)] = min(a, b)
    out = truth.copy()
    for a in parent:
        out[truth == a] = root(a)
    return out


def _observed_points(x, Z):
    """(m, 2) world positions of range-bearing observations Z (2, m) taken from pose x."""
    a = x[2] + Z[1]
    return np.column_stack([x[0] + Z[0] * np.cos(a), x[1] + Z[0] * np.sin(a)])


def _nearest_is_right(points, ids, keys, positions):
    """Per observation: whether the nearest of ``positions`` (keys ``keys``) is its own id."""
    d = np.linalg.norm(positions[None, :, :] - points[:, None, :], axis=2)
    return np.asarray(keys)[np.argmin(d, axis=1)] == ids


def known_id_nearest_neighbour(periods=(100, 20), **run_options) -> list[dict]:
    """How well the plainest association could do if every *past* id were known: the known-id pipeline runs
    (``run_victoria_park(None, optimization_period=period, **run_options)``) and, just before each scan is added,
    every re-observation of an already mapped tree is placed in the world from the pipeline's current pose
    estimate and paired with the nearest mapped tree. Per period: re_observations, nn_correct (fraction paired
    with its own tree), median_error and p90_error (m, distance from the placed observation to its own tree)."""
    periods = () if isinstance(periods, (str, bytes)) or not hasattr(periods, "__iter__") else tuple(periods)
    if not periods:
        raise ValueError("periods must be a non-empty sequence of positive integers (poses)")
    out = []
    for period in periods:
        period = integer(period, "periods", minimum=1)
        right, error = [], []

        def probe(x, Z, ids, vertices):
            seen = np.array([i in vertices for i in ids.tolist()], dtype=bool)
            if not seen.any():
                return
            keys = list(vertices)
            positions = np.array([vertices[k].estimate for k in keys])
            pts = _observed_points(x, Z[:, seen])
            right.extend(_nearest_is_right(pts, ids[seen], keys, positions).tolist())
            own = np.array([vertices[i].estimate for i in ids[seen].tolist()])
            error.extend(np.linalg.norm(pts - own, axis=1).tolist())

        run_victoria_park(None, optimization_period=period, scan_probe=probe, **run_options)
        out.append({"period": period, "re_observations": len(right), "nn_correct": float(np.mean(right)),
                    "median_error": float(np.median(error)), "p90_error": float(np.percentile(error, 90))})
    return out


def smoothed_nearest_neighbour(reference) -> float:
    """The same nearest-neighbour pairing with hindsight: every observation placed from the *final* known-id
    solution's pose and paired with the nearest of its final landmarks; the fraction paired with its own id."""
    if not getattr(reference, "landmark_vertices", None):
        raise ValueError("reference: a known-id run (run_victoria_park(None) or res.reference) is needed")
    keys = sorted(reference.landmark_vertices)
    positions = np.array([reference.landmark_vertices[k].estimate for k in keys])
    stream = victoria_park_scans(read_dataset("victoria_park"))
    index = {stream[0][1]: 0}
    for item in stream:
        if item[0] == "odometry":
            index[item[2]] = len(index)
    pose = poses(reference)
    right = [_nearest_is_right(_observed_points(pose[index[item[1]]], item[2]), item[4], keys, positions)
             for item in stream if item[0] == "scan"]
    return float(np.mean(np.concatenate(right)))


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


def merge_outcomes(res) -> list[dict]:
    """Every loop-closure merge of an online run, judged against the file's ids after the fact: the merged
    track's observations against the old landmark's own (a merge is *wrong* when their majority ids differ).
    One row per merge (scan order): track, old, scan (−1 when not logged), wrong, undone, T (the verification's
    statistic, NaN when not verified). Merges kept are read from the tracks, undone ones from ``merge_log``."""
    fe = getattr(res, "frontend", None)
    if fe is None:
        raise ValueError("res: an online run (run_victoria_park with data_association set) is needed")
    truth = np.asarray(res.truth)
    logged = {(m["track"], m["old"]): m for m in getattr(fe, "merge_log", [])}
    pairs = {(t.key, t.alias_of) for t in fe.tracks if t.alias_of >= 0} | set(logged)
    rows = []
    for key, old in pairs:
        m = logged.get((key, old), {})
        wrong = _majority(truth[fe.tracks[key].observations]) != _majority(truth[fe.tracks[old].observations])
        scan = m.get("scan", getattr(fe, "merge_scans", {}).get(key, -1))
        rows.append({"track": key, "old": old, "scan": scan, "wrong": bool(wrong),
                     "undone": bool(m.get("undone", False)), "T": m.get("T", float("nan"))})
    return sorted(rows, key=lambda r: (r["scan"], r["track"]))


def duplicate_landmarks(res) -> list[dict]:
    """Loops left open, after the fact: every confirmed landmark of an online run whose majority file id is the
    majority id of a landmark confirmed before it (a tree mapped twice). One row per duplicate, in the order of
    confirmation: key, id, scan (its confirmation), first (the earlier landmark's key), first_scan. The file's own
    near-duplicate ids (``near_duplicate_ids``) can appear here without a loop being open."""
    fe = getattr(res, "frontend", None)
    if fe is None:
        raise ValueError("res: an online run (run_victoria_park with data_association set) is needed")
    assigned, truth = fe.observation_assignment(), np.asarray(res.truth)
    owner, rows = {}, []
    for t in sorted(fe.confirmed_tracks(), key=lambda t: (t.end, t.key)):
        lid = _majority(truth[assigned == t.key])
        if lid in owner:
            first = owner[lid]
            rows.append({"key": t.key, "id": lid, "scan": t.end, "first": first.key, "first_scan": first.end})
        else:
            owner[lid] = t
    return rows
