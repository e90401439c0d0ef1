"""Graph pruning for DriveBot SLAM (coursework Q3b): drop landmark observation edges before optimising.

Graph pruning keeps every vertex the SLAM system needs but deletes *edges* that add little information, so
the Hessian H = Σ JᵀΩJ has fewer non-zeros, each Levenberg–Marquardt iteration is cheaper, and (with fewer
residuals) the optimiser converges faster. Deleting vertices properly would need marginalisation, which
creates fill-in between the neighbours of the deleted vertex; deleting edges does not.

Every heuristic here only removes **landmark range-bearing edges**; the kinematics chain is untouched, so
with prediction edges kept no vehicle vertex is orphaned. Each landmark always keeps at least one
observation (if a rule would drop all of them, its earliest edge is kept), so no landmark vertex is deleted
by the graph's orphan rule.

Three heuristics, each a callable object usable as the SLAM system's ``pre_optimization_hook(system)``
(called before every optimisation, so it prunes the edges added since the last call — the rules are
idempotent on vertices already pruned):

- :class:`KeepKPerVertex` — keep at most ``k`` landmark edges per vehicle vertex, chosen uniformly at random
  from a seeded ``numpy.random.Generator`` (ties broken by a random key; rank within the vertex < k is
  kept). Motivated by the 30 m laser of q3_a: a pose sees ≈ 3 landmarks on average (6 equations for its
  3 DOF), and consecutive poses see the same landmarks from almost the same place.
- :class:`KeyframePruning` — keyframes: a vertex is on a *straight segment* when its smoothed turn rate
  |ψ̇| = |Δψ|/ΔT (moving average over ``window`` ticks of the current heading estimates) is below
  ``rate_threshold``; on straights only every ``stride``-th vertex (a keyframe) keeps its landmark edges,
  in turns all vertices keep theirs (the heading changes fast there and the observations pin it down).
- :class:`AlternateVertexPruning` — drop the landmark edges of every vertex whose index is not a multiple
  of ``stride`` (stride 2: every other vertex; the coursework's "method 2").

The selection rules are pure array functions (:func:`keep_k_per_group`, :func:`straight_segment_mask`,
:func:`protect_landmarks`) vectorised over all edges; only the final ``remove_edge`` calls are per edge,
because the graph's object API removes one edge at a time.
"""
from __future__ import annotations

import numbers

import numpy as np

from ..graph.angles import wrap_angle
from ..validation import int_array, integer, positive_number, rng_seed

__all__ = ["keep_k_per_group", "straight_segment_mask", "stride_mask", "protect_landmarks",
           "landmark_edge_table", "PruningHook", "KeepKPerVertex", "KeyframePruning",
           "AlternateVertexPruning", "q3b_hook"]


# ----------------------------------------------------------------------------------------------------
# validation
# ----------------------------------------------------------------------------------------------------






# ----------------------------------------------------------------------------------------------------
# selection rules on arrays
# ----------------------------------------------------------------------------------------------------
def keep_k_per_group(group, k, rng) -> np.ndarray:
    """Boolean keep-mask over items (edges) keeping at most ``k`` items of each group (vehicle vertex).

    Items of a group are ranked by a uniform random key drawn from ``rng`` (a numpy Generator); the ``k``
    lowest keys are kept. Groups with ≤ k items keep everything, so applying the rule again to its own
    output removes nothing (idempotent). Vectorised: one lexsort, ranks from group starts.
    """
    group = int_array(group, "group")
    k = integer(k, "k", minimum=0)
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    n = group.size
    keep = np.zeros(n, bool)
    if n == 0:
        return keep
    key = rng.random(n)
    order = np.lexsort((key, group))
    g = group[order]
    new_group = np.r_[True, g[1:] != g[:-1]]
    starts = np.flatnonzero(new_group)
    first_of = starts[np.cumsum(new_group) - 1]
    rank = np.arange(n) - first_of
    keep[order] = rank < k
    return keep


def stride_mask(index, stride, offset=0) -> np.ndarray:
    """True where ``(index − offset) % stride == 0`` (the vertices that keep their landmark edges)."""
    index = int_array(index, "index")
    stride = integer(stride, "stride", minimum=1)
    if isinstance(offset, bool) or not isinstance(offset, numbers.Integral):
        raise ValueError(f"offset must be an integer, got {offset!r}")
    return (index - int(offset)) % stride == 0


def straight_segment_mask(headings, dt, rate_threshold=0.05, window=11) -> np.ndarray:
    """True for vertices whose smoothed turn rate is below ``rate_threshold`` (rad/s).

    ψ̇_k = wrap(ψ_{k+1} − ψ_k)/ΔT_k between consecutive vertices (``headings`` (N,), ``dt`` (N−1,) or a
    scalar), smoothed by a centred moving average over ``window`` rates (odd; truncated at the ends); a
    vertex's rate is the mean of its two adjacent smoothed rates (one at the ends). The moving average
    suppresses the odometry noise in the estimates (σ_ψ̇ = 1°/s per tick → 1°/s/√window).
    """
    psi = np.asarray(headings, dtype=float)
    if psi.ndim != 1 or not np.all(np.isfinite(psi)):
        raise ValueError(f"headings must be a finite 1-D array, got shape {psi.shape}")
    n = psi.size
    dt = np.broadcast_to(np.asarray(dt, dtype=float), (max(n - 1, 0),)) if np.ndim(dt) == 0 \
        else np.asarray(dt, dtype=float)
    if dt.shape != (max(n - 1, 0),) or np.any(~np.isfinite(dt)) or np.any(dt <= 0):
        raise ValueError(f"dt must be a positive scalar or an array of shape ({max(n - 1, 0)},)")
    rate_threshold = positive_number(rate_threshold, "rate_threshold")
    window = integer(window, "window", minimum=1)
    if window % 2 == 0:
        raise ValueError(f"window must be odd, got {window}")
    if n < 2:
        return np.ones(n, bool)
    rate = np.abs(wrap_angle(np.diff(psi))) / dt
    half = window // 2
    c = np.concatenate([[0.0], np.cumsum(rate)])
    lo = np.clip(np.arange(rate.size) - half, 0, rate.size)
    hi = np.clip(np.arange(rate.size) + half + 1, 0, rate.size)
    smooth = (c[hi] - c[lo]) / (hi - lo)
    left = np.r_[smooth[:1], smooth]
    right = np.r_[smooth, smooth[-1:]]
    return 0.5 * (left + right) < rate_threshold


def protect_landmarks(keep, landmark) -> np.ndarray:
    """Return a copy of ``keep`` in which every landmark keeps at least one edge (its first one).

    ``landmark`` (E,) gives each edge's landmark in creation order; a landmark whose edges would all be
    dropped gets its earliest edge back, so the graph's orphan rule never deletes a landmark vertex.
    """
    keep = np.asarray(keep)
    landmark = int_array(landmark, "landmark")
    if keep.dtype != bool or keep.shape != landmark.shape:
        raise ValueError(f"keep must be a boolean array of shape {landmark.shape}, got {keep.dtype} {keep.shape}")
    out = keep.copy()
    if landmark.size == 0:
        return out
    ids, first, inverse = np.unique(landmark, return_index=True, return_inverse=True)
    kept_per = np.bincount(inverse, weights=keep, minlength=ids.size)
    out[first[kept_per == 0]] = True
    return out


# ----------------------------------------------------------------------------------------------------
# the graph side
# ----------------------------------------------------------------------------------------------------
def landmark_edge_table(system, dt_default=0.1):
    """Arrays describing the current landmark edges of a graph, in the graph's creation order.

    ``system`` is a DriveBot SLAM system (anything with a ``graph`` attribute) or a ``SparseOptimizer``.
    Landmark edges are the edges joining a pose vertex (``VertexSE2``) to a point vertex
    (``VertexPointXY``). Returns a dict with

    - ``edges``    list of the E edge objects;
    - ``vertex``   (E,) the id of each edge's vehicle vertex (ids are allocated in creation order, so
      strides over ids are strides over ticks, and they stay stable when other vertices leave the graph);
    - ``landmark`` (E,) the id of each edge's landmark vertex;
    - ``vehicle_ids`` (N,), ``headings`` (N,) and ``dt`` (N−1,) of the vehicle vertices in the graph, in
      creation order (dt from the vertices' ``time`` attribute when they have one, else ``dt_default``
      per id step); ``vertex_pos`` (E,) each edge's vehicle vertex as an index into those arrays.
    """
    from ..graph import VertexPointXY, VertexSE2

    graph = getattr(system, "graph", system)
    if not (hasattr(graph, "edges") and hasattr(graph, "vertices") and hasattr(graph, "remove_edge")):
        raise ValueError(f"system must be a SLAM system with a graph or a SparseOptimizer, got {type(system).__name__}")
    dt_default = positive_number(dt_default, "dt_default")
    edges, vid, lid = [], [], []
    for e in graph.edges():
        vs = e.vertices()
        if len(vs) == 2 and isinstance(vs[0], VertexSE2) and isinstance(vs[1], VertexPointXY):
            edges.append(e)
            vid.append(vs[0].id)
            lid.append(vs[1].id)
    vehicles = [v for v in graph.vertices() if isinstance(v, VertexSE2)]
    vehicle_ids = np.array([v.id for v in vehicles], dtype=np.int64)
    headings = np.array([v.estimate[2] for v in vehicles], dtype=float)
    times = [getattr(v, "time", None) for v in vehicles]
    if vehicles and all(t is not None for t in times):
        dt = np.diff(np.asarray(times, dtype=float))
    else:
        dt = dt_default * np.diff(vehicle_ids).astype(float)
    dt = np.where(dt > 0, dt, dt_default)
    vid = np.array(vid, dtype=np.int64)
    if np.all(np.diff(vehicle_ids) > 0):
        pos = np.searchsorted(vehicle_ids, vid)
    else:
        where = {v: i for i, v in enumerate(vehicle_ids.tolist())}
        pos = np.array([where[x] for x in vid.tolist()], dtype=np.int64)
    return {"edges": edges, "vertex": vid, "landmark": np.array(lid, dtype=np.int64),
            "vehicle_ids": vehicle_ids, "headings": headings, "dt": dt, "vertex_pos": pos.astype(np.int64)}


class PruningHook:
    """Base class: ``hook(system)`` removes the landmark edges that ``select(table)`` does not keep.

    Counters: ``calls``, ``removed`` (edges removed in total), ``history`` (list of (edges seen, removed)
    per call).
    """

    def __init__(self):
        self.calls = 0
        self.removed = 0
        self.history = []

    def select(self, table) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def __call__(self, system):
        # Q3b: one table of every landmark (range-bearing) edge now in the graph, in creation order.
        table = landmark_edge_table(system)
        # Q3b: the heuristic (a subclass's select) decides per edge; then every landmark keeps at least one
        # edge, so the graph's orphan rule never deletes a landmark vertex.
        keep = self.select(table)
        keep = protect_landmarks(keep, table["landmark"])
        drop = np.flatnonzero(~keep)
        graph = getattr(system, "graph", system)
        edges = table["edges"]
        for i in drop.tolist():   # Q3b: remove the edges (the graph API removes one edge at a time)
            graph.remove_edge(edges[i])
        self.calls += 1
        self.removed += int(drop.size)
        self.history.append((len(edges), int(drop.size)))
        return int(drop.size)

    def describe(self) -> str:
        return type(self).__name__


class KeepKPerVertex(PruningHook):
    """Keep at most ``k`` landmark edges per vehicle vertex, chosen at random (``seed``: a non-negative integer,
    a sequence of them or a numpy Generator)."""

    def __init__(self, k=2, seed=0):
        super().__init__()
        self.k = integer(k, "k", minimum=1)
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(rng_seed(seed))

    def select(self, table):
        return keep_k_per_group(table["vertex"], self.k, self.rng)

    def describe(self):
        return f"keep ≤ {self.k} per vertex"


class KeyframePruning(PruningHook):
    """On straight segments keep landmark edges only on every ``stride``-th vertex; keep all in turns.

    The coursework's q3_b heuristic (:func:`q3b_hook`, ``run_question("q3_b")``).
    """

    def __init__(self, stride=5, rate_threshold=0.05, window=11):
        super().__init__()
        self.stride = integer(stride, "stride", minimum=1)
        self.rate_threshold = positive_number(rate_threshold, "rate_threshold")
        self.window = integer(window, "window", minimum=1)
        if self.window % 2 == 0:
            raise ValueError(f"window must be odd, got {window}")

    def select(self, table):
        # Q3b: classify every vehicle vertex from its *current* heading estimates: straight when the turn rate
        # |Δψ|/ΔT, averaged over `window` ticks, is below `rate_threshold` (rad/s). Recomputed at every call, so
        # vertices added since the last optimisation are classified with the freshly optimised headings.
        straight = straight_segment_mask(table["headings"], table["dt"], self.rate_threshold, self.window)
        # Q3b: keyframes are every `stride`-th tick (by vertex id, i.e. by tick, stable across calls).
        keyframe = stride_mask(table["vehicle_ids"], self.stride)
        # Q3b: a vertex keeps its landmark edges when it is a keyframe or lies in a turn; all other landmark
        # edges are removed by PruningHook.__call__ (which also keeps one edge per landmark, see
        # protect_landmarks). Kinematics edges are never touched, so no vertex is orphaned.
        vertex_keeps = ~straight | keyframe
        return vertex_keeps[table["vertex_pos"]]

    def describe(self):
        return f"keyframes every {self.stride} on straights"


def q3b_hook(stride=5, rate_threshold=0.05, window=11) -> KeyframePruning:
    """The pruning hook of the coursework's q3_b run (a fresh object per run: hooks count their calls).

    Q3b: the SLAM system calls it before every optimisation (every 500 ticks and at the end of the run), so
    observations are thinned as the graph grows; see :class:`KeyframePruning`.
    """
    # Q3b: defaults chosen for the q3_a scenario (0.1 s ticks, 30 m laser): on a straight, 5 ticks = 0.5 s
    # between observed poses; 0.05 rad/s ≈ 3°/s lies well below the turn rates at the corners, and an
    # 11-tick moving average suppresses the 1°/s odometry noise in the heading estimates.
    return KeyframePruning(stride=stride, rate_threshold=rate_threshold, window=window)


class AlternateVertexPruning(PruningHook):
    """Drop every landmark edge of vertices whose index is not a multiple of ``stride``."""

    def __init__(self, stride=2):
        super().__init__()
        self.stride = integer(stride, "stride", minimum=2)

    def select(self, table):
        return stride_mask(table["vertex"], self.stride)

    def describe(self):
        return f"observations on every {self.stride}nd vertex" if self.stride == 2 else \
            f"observations on every {self.stride}th vertex"
