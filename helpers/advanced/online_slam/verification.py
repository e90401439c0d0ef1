"""Loop-closure merges verified after the next optimisation, and undone when the graph refuses them.

A merge (``LoopClosure._closure_stage`` or ``_merge_duplicates`` → ``OnlineFrontEnd._merge``) is the hypothesis
"tentative landmark t is the old landmark l": t's observations become edges to l's vertex. On Victoria Park a
closure may rest on a single pairing (``closure_support`` 1), and one wrong merge bends the map and misleads every
association after it. So a merge stays *unverified* until the next ``refresh()`` — called after an optimisation,
when the graph has absorbed it — and is then tested.

**The test** (a score test of the split hypothesis, exact for the linearised graph). Give t's edges their own
landmark m_t = m_l + δ. The merge is δ = 0. At the optimised estimate of the merged graph, with ½χ² the cost, e_i
the errors, Ω_i the information, J_i the Jacobians of t's edges i (pose p_i, landmark):

    b = Σ_i J_{m,i}ᵀ Ω_i e_i                      gradient of ½χ² with respect to δ at δ = 0
    H_δδ = Σ_i J_{m,i}ᵀ Ω_i J_{m,i},
    H_δx = [Σ_{i: p_i = p} J_{m,i}ᵀ Ω_i J_{p,i} for each pose p of t's edges | H_δδ for m_l]
    S = H_δδ − H_δx Σ_x H_xδ                     Σ_x: the joint covariance of those poses and m_l (columns of H⁻¹)
    T = bᵀ S⁻¹ b

T is the drop of χ² the split would buy (the Newton step in δ, with every other vertex re-optimised); if the merge
is right, T is χ² with ``landmark_dimension`` degrees of freedom. A merge with T above the χ² quantile at
``verify_n_sigma`` (c = 2Φ(n_σ) − 1) is **undone**. The χ² of t's edges alone is no test: the optimiser bends the
trajectory to satisfy a wrong merge, and t's edges then look consistent while the odometry pays.

**The undo.** t becomes a confirmed landmark with its own vertex — the split is the hypothesis the test preferred.
It does not go back to tentative: its ``n_confirm`` observations already passed the confirmation rule (it is no
clutter), and as a tentative landmark it would be offered to the same old landmark again. Its vertex starts at the
mean of the inverse observations of its edges from the current pose estimates; its edges are re-created on it (same
pose, measurement, information) before the edges to m_l are removed, so no vertex is left without edges. The graph
is then re-optimised (``verify_iterations`` iterations of "lm-gtsam", structure rebuilt) before ``refresh``
factorises H, so the front-end's next scans see the map without the wrong closure. The observation log needs no
change: it records track keys, and t's key now owns a vertex.

A merge whose edges cannot be told apart (two edges from one pose to m_l) or whose test cannot be computed (H not
positive definite) is left as it is and counted as ``merges_unverified``: a failed verification changes nothing.
``merge_log`` keeps one entry per verified merge (track, old landmark, scan, T, χ² of t's edges, edges, undone);
``merge_scans`` the scan of every merge, verified or not.

Measured on Victoria Park (wider noise model, ``n_confirm`` 3, one deterministic run each; off by default): at
period 10 no merge is refused and the run is unchanged (agreement 0.930). On the neighbours that collapse the test
refuses most wrong merges (period 8 at 2.5σ: 5 wrong merges left → 0, agreement 0.54 → 0.71) but does not remove
the collapse (period 12, odometry × 8, ``n_confirm`` 4: 0.37–0.49), and it refuses right merges too (T up to 52:
the file's odometry is biased, so a right closure can look inconsistent) — with ``n_sigma`` 4 at period 12 it
turns a good run (0.924) into a collapse (0.625). The collapse starts earlier: revisited trees fall outside the
tracking gate of their *trusted* landmarks and are mapped twice (``vp_analysis.duplicate_landmarks``: from scan
≈ 455 on; the first wrong merge comes at 898). Verification cannot close a loop that no merge proposed.
"""
from __future__ import annotations

import time
from bisect import bisect_right

import numpy as np

from ...gaussian import chi2inv, confidence_level
from ...validation import boolean, integer, positive_number
from .covariance import MarginalColumns
from .tracks import CONFIRMED

__all__ = ["MergeVerification", "split_statistic"]


def split_statistic(edges, landmark, covariance) -> tuple[float, float]:
    """(T, χ² of ``edges``): the score statistic of the module docstring for giving ``edges`` (range-bearing-like
    edges from a pose, slot 0, to ``landmark``, slot 1) a landmark of their own. ``covariance(vertices)`` returns
    the joint covariance of a list of vertices (fixed ones zero). NaN when S is not positive definite."""
    poses = []
    for e in edges:
        if e.vertex(1) is not landmark:
            raise ValueError("edges: every edge must end at the landmark being tested")
        if not any(p is e.vertex(0) for p in poses):
            poses.append(e.vertex(0))
    ld = type(landmark).dimension
    dims = [type(p).dimension for p in poses]
    offs = np.concatenate([[0], np.cumsum(dims)]).astype(int)
    b, h_dd = np.zeros(ld), np.zeros((ld, ld))
    A = np.zeros((ld, offs[-1] + ld))
    chi2 = 0.0
    for e in edges:
        err, (jp, jm), om = e.error(), e.jacobians(), e.information
        k = next(i for i, p in enumerate(poses) if p is e.vertex(0))
        b += jm.T @ om @ err
        h_dd += jm.T @ om @ jm
        A[:, offs[k]:offs[k + 1]] += jm.T @ om @ jp
        chi2 += float(err @ om @ err)
    A[:, offs[-1]:] = h_dd
    S = h_dd - A @ covariance(poses + [landmark]) @ A.T
    S = 0.5 * (S + S.T)
    if not np.all(np.isfinite(S)) or np.linalg.eigvalsh(S)[0] <= 1e-12 * max(np.abs(S).max(), 1e-300):
        return float("nan"), chi2
    return float(b @ np.linalg.solve(S, b)), chi2


class MergeVerification:
    """Mixin of ``OnlineFrontEnd``: merge verification with undo (module docstring)."""

    def _init_verification(self, verify_merges, verify_n_sigma, verify_iterations):
        self.verify_merges = boolean(verify_merges, "verify_merges")
        self.verify_n_sigma = positive_number(verify_n_sigma, "verify_n_sigma")
        self.verify_iterations = integer(verify_iterations, "verify_iterations", minimum=1)
        level = confidence_level(self.verify_n_sigma)
        if not level < 1.0:
            raise ValueError(f"verify_n_sigma must be small enough for a χ² quantile (2Φ(n) − 1 < 1 in floating "
                             f"point, n ≲ 8), got {verify_n_sigma!r}")
        self._verify_gate = float(chi2inv(level, self.model.landmark_dimension))
        self._unverified = []          # (track, old track, scan) merged since the last refresh
        self._scan_firsts, self._scan_poses = [], []   # pose vertex current from scan _scan_firsts[i] on
        self.merge_log = []
        self.merge_scans = {}          # track key -> scan of its (last) merge, verified or not
        self.stats.update(merges_verified=0, merges_undone=0, merges_unverified=0, verify_time=0.0)

    def _note_pose(self, vertex):
        """``vertex`` is the pose of every scan from the next one on (observations → pose for the undo)."""
        if self._scan_firsts and self._scan_firsts[-1] == self.scan_count:
            self._scan_poses[-1] = vertex
        else:
            self._scan_firsts.append(self.scan_count)
            self._scan_poses.append(vertex)

    def _pose_of_scan(self, scan):
        return self._scan_poses[bisect_right(self._scan_firsts, scan) - 1]

    def _note_merge(self, t, old, scan):
        self.merge_scans[t.key] = scan
        if self.verify_merges:
            self._unverified.append((t, old, scan))

    def _merge_edges(self, t, old):
        """The graph edges of t's observations (they end at old's vertex), or None when they cannot be told
        apart or are not all in the graph."""
        out = []
        for obs in t.observations:
            pose = self._pose_of_scan(self.observation_log["scan"][obs])
            hits = [e for e in pose.edges() if e.vertex(1) is old.vertex and e.vertex(0) is pose]
            if len(hits) != 1 or any(e is h for e in out for h in hits):
                return None
            out.append(hits[0])
        return out

    def _verify_pending_merges(self) -> None:
        """Test every merge made since the last refresh (the graph is optimised, its structure built); undo the
        refused ones and re-optimise. Called by ``refresh`` before it factorises."""
        if not self._unverified:
            return
        t0 = time.perf_counter()
        todo, self._unverified = self._unverified, []
        work = []
        for t, old, scan in todo:
            edges = None if t.alias_of != old.key or t.status != CONFIRMED else self._merge_edges(t, old)
            if edges is None or old.vertex.number_of_edges() <= len(edges):
                self.stats["merges_unverified"] += 1
                continue
            work.append((t, old, scan, edges))
        columns = MarginalColumns()
        vertices = list({id(v): v for *_, edges in work for e in edges for v in e.vertices()}.values())
        if not work or not columns.refresh(self.graph, vertices):
            self.stats["merges_unverified"] += len(work)
            self.stats["verify_time"] += time.perf_counter() - t0
            return
        refused = []
        for t, old, scan, edges in work:
            T, chi2 = split_statistic(edges, old.vertex, columns.joint)
            bad = bool(T > self._verify_gate)          # NaN: not computable, kept
            self.stats["merges_verified" if np.isfinite(T) else "merges_unverified"] += 1
            self.merge_log.append({"track": t.key, "old": old.key, "scan": scan, "T": T, "chi2": chi2,
                                   "edges": len(edges), "undone": bad})
            if bad:
                refused.append((t, edges))
        for t, edges in refused:
            self._undo_merge(t, edges)
        if refused:
            self.graph.initialize_optimization()
            self.graph.optimize(self.verify_iterations, algorithm="lm-gtsam")
        self.stats["verify_time"] += time.perf_counter() - t0

    def _undo_merge(self, t, edges):
        """t gets its own landmark vertex, and its edges move to it (module docstring)."""
        est = np.mean([self.model.inverse(e.vertex(0).estimate, e.measurement)[0] for e in edges], axis=0)
        z = np.array([e.measurement for e in edges])
        info = np.array([e.information for e in edges])
        vertex = self.landmark_factory(t.key, est)
        self.graph.add_vertex(vertex)
        try:
            self.graph.add_edges(type(edges[0]), [(e.vertex(0), vertex) for e in edges], z, info)
        except Exception:
            self.graph.remove_vertex(vertex)          # nothing else has changed yet
            raise
        for e in edges:
            self.graph.remove_edge(e)
        t.vertex, t.alias_of = vertex, -1
        self.stats["merges_undone"] += 1
