"""The online graph-SLAM front-end: each scan's observations arrive without ids and are associated here.

Per scan (``process_scan(Z, R)``, Z the d×m observations of the current pose):

1. **Candidates**: the landmarks — confirmed or tentative — whose predicted observation from the current pose
   estimate falls in the sensor footprint, widened by the margins and n_σ pose standard deviations.
2. **Joint predicted density** of the candidates. The stacked state v = [x; m_1; …; m_k] (pose and candidate
   landmarks) has the joint covariance Σ_v with every cross-block. It comes from two sources: the factorisation
   of H at the last refresh (``MarginalColumns``: only the columns of the few vertices needed, never a dense
   inverse) for the landmarks it covers, and the ``LocalWindow`` for what is newer — the pose propagated by
   odometry since the refresh and the landmarks created since. With ŷ_i the predicted observation of landmark
   i in the association space of the model, J = ∂[ŷ_1; …; ŷ_k]/∂v and R_i the sensor noise there,

       density = N(ŷ, J Σ_v Jᵀ + blkdiag(R_1, …, R_k)).

   The approximation: between refreshes the pose is the last refresh's optimised pose moved by odometry, and
   new observations are not fused until the next refresh (covariances conservative, never optimistic).
3. **Tracking** — the chosen L09 algorithm ("nn", "mahalanobis", "ml", "jcbb", ``algorithms``) pairs the
   observations with the *trusted* candidates: tentative landmarks and landmarks whose position relative to the
   vehicle is known to ``closure_sigma`` metres (``decisions.relative_sigma``). Pairings with an equally good
   alternative are dropped (``decisions.ambiguous_pairings``). A pairing with a confirmed landmark adds a
   range-bearing edge at once; with a tentative one it waits in the track. Unpaired observations start
   tentative landmarks, unless they lie inside the exclusion gate (``rules.exclusion_n_sigma``, wider than the
   pairing gate) of a trusted candidate: then they are discarded — at 3σ one true observation in 370 falls
   outside the pairing gate, and it must not start a duplicate of its landmark.
4. **Loop closure** — landmarks with wider gates (not seen for long) are never paired with a raw observation:
   inside such a gate a spurious detection is as likely as the landmark. A tentative landmark that reaches
   ``n_confirm`` observations is first offered to them: the algorithm pairs the current observations of all
   tentative landmarks confirmable in this scan with the untrusted candidates. A pairing that is unambiguous and
   supported by at least ``closure_support`` pairings in all (a constellation: one pairing carries no joint
   evidence) **merges** the tentative landmark into the old one (its observations become edges to the old vertex;
   the optimiser closes the loop at the next refresh). A tentative landmark individually compatible with an old
   one but not merged waits (at most ``closure_patience`` scans, then dropped); one compatible with none becomes
   a new landmark.
5. Tentative landmarks not re-observed while predicted in the footprint, or too old, are dropped (``tracks``).

``refresh()`` is called after each optimisation (the graph's structure must be built): it factorises H at the
new estimates, re-anchors the window at the current pose and carries the surviving tentative landmarks over.

Everything the front-end decided is logged per observation (``observation_log``) for evaluation against a truth
the front-end never sees.
"""
from __future__ import annotations

import time

import numpy as np

from ...association.common import problem_from_cov
from ...gaussian import chi2inv, confidence_level
from ...graph import VertexPointXY
from ...validation import boolean, integer, positive_number
from .algorithms import associate, check_algorithm, check_options
from .closure import LoopClosure
from .covariance import FACTORISE, MarginalColumns, hessian_factors
from .decisions import ambiguous_pairings, largest_sd, relative_sigma, sub_problem
from .late import LateAssociation
from .models import motion_jacobians
from .scan_guard import ScanUndo, check_graph_and_model, check_pose_edge, check_pose_vertex, check_scan
from .scan_kernels import block_largest_sd
from .tracks import CONFIRMED, DROPPED, TENTATIVE, ConfirmationRules, Track
from .verification import MergeVerification
from .window import LocalWindow

__all__ = ["OnlineFrontEnd", "ScanResult"]


class ScanResult:
    """What one scan produced: ``labels`` (m,) track key of each observation (−1: discarded), ``new`` keys of the
    tracks it started, ``confirmed`` / ``merged`` ((key, old key)) / ``postponed`` / ``dropped`` decided in it,
    ``candidates`` keys, ``association`` (the tracking stage's Association, None without candidates)."""

    __slots__ = ("labels", "new", "confirmed", "merged", "postponed", "dropped", "candidates", "association")

    def __init__(self, m):
        self.labels = np.full(m, -1, dtype=np.int64)
        self.new, self.confirmed, self.merged, self.postponed, self.dropped = [], [], [], [], []
        self.candidates = []
        self.association = None


def _default_factory(key, estimate):
    return VertexPointXY(None, estimate)


class OnlineFrontEnd(LoopClosure, MergeVerification, LateAssociation):
    """Online data association for a growing pose graph (module docstring).

    Parameters
    ----------
    graph : the ``FastOptimizer`` the SLAM system builds.
    model : the measurement model (``models.RangeBearingModel``).
    data_association : "nn", "mahalanobis", "ml" or "jcbb".
    n_sigma : gate width of the algorithms (χ² gates at c = 2Φ(n_σ) − 1) and of the front-end's own tests.
    algorithm_options : extra options of the algorithm (``algorithms``).
    rules : ``ConfirmationRules`` (default: confirm after 3 observations, drop after 3 misses or 10 scans).
    landmark_factory : callable(key, estimate) → a new landmark vertex (default ``VertexPointXY``).
    reject_ambiguous : drop pairings that have an equally good alternative (``decisions``).
    closure_sigma, closure_support, closure_patience : the loop-closure stage (module docstring, step 4).
    verify_merges, verify_n_sigma, verify_iterations : test every merge after the next optimisation and undo the
        refused ones, re-optimising with that many iterations (``verification``; default off).
    late_association, late_n_sigma, late_radius : keep the observations left out of the map (dropped tentative
        landmarks, discarded observations) and pair them with a confirmed landmark after a later optimisation, or
        make a landmark of those that agree among themselves (``late``; default off).

    Use: ``start(first_pose)``; per new pose ``add_pose(odometry_edge)``; per scan ``process_scan(Z, R)``; after
    each optimisation ``refresh()``. Arguments are checked before anything changes (ValueError naming them), and a
    scan that fails part-way is undone (``scan_guard``).
    """

    def __init__(self, graph, model, data_association: str = "jcbb", n_sigma: float = 3.0,
                 algorithm_options=None, rules: ConfirmationRules | None = None, landmark_factory=None,
                 reject_ambiguous: bool = True, closure_sigma: float = 0.5, closure_support: int = 2,
                 closure_patience: int = 50, verify_merges: bool = False, verify_n_sigma: float = 3.0,
                 verify_iterations: int = 10, late_association: bool = False, late_n_sigma: float = 2.0,
                 late_radius: float = 5.0):
        check_graph_and_model(graph, model)
        self.algorithm = check_algorithm(data_association)
        self.options = check_options(self.algorithm, algorithm_options)
        self.n_sigma = positive_number(n_sigma, "n_sigma")
        self.rules = ConfirmationRules() if rules is None else rules
        if not isinstance(self.rules, ConfirmationRules):
            raise ValueError(f"rules must be a ConfirmationRules, got {type(self.rules).__name__}")
        if landmark_factory is not None and not callable(landmark_factory):
            raise ValueError(f"landmark_factory must be callable(key, estimate) or None, got {landmark_factory!r}")
        self.reject_ambiguous = boolean(reject_ambiguous, "reject_ambiguous")
        self.closure_sigma = positive_number(closure_sigma, "closure_sigma")
        self.closure_support = integer(closure_support, "closure_support", minimum=1)
        self.closure_patience = integer(closure_patience, "closure_patience", minimum=1)
        self.graph, self.model = graph, model
        self.landmark_factory = landmark_factory or _default_factory
        self.tracks: list[Track] = []
        self.window = LocalWindow()
        self.columns = MarginalColumns()
        self.pose = None
        self.anchors = []
        self._factorised = []
        self._factorised_pos = np.zeros((0, model.landmark_dimension))
        self.scan_count = 0
        self.observation_log = {"scan": [], "column": [], "key": []}
        self.stats = {"scan_time": 0.0, "association_time": 0.0, "refresh_time": 0.0, "refreshes": 0, "nodes": 0,
                      "budget_exhausted": 0, "candidates": 0, "scans_associated": 0, "ambiguous_rejected": 0,
                      "merges": 0, "postponements": 0, "pose_time": 0.0}
        self._ic_gate = float(chi2inv(confidence_level(self.n_sigma), model.dimension))
        self._checked_noise = {}
        self._undo = None                       # the running scan's ScanUndo
        ex = self.rules.exclusion_n_sigma
        self._exclusion_gate = None if ex is None else float(chi2inv(confidence_level(ex), model.dimension))
        self._init_verification(verify_merges, verify_n_sigma, verify_iterations)
        self._init_late(late_association, late_n_sigma, late_radius)

    # ================================================================================= poses and refreshes
    def start(self, pose_vertex) -> None:
        """The first pose (normally fixed): the window is anchored there with zero covariance."""
        check_pose_vertex(pose_vertex, self.graph, self.model)
        self.pose = pose_vertex
        self.anchors = [pose_vertex]
        self.columns = MarginalColumns()
        self.columns.register_without_factorisation([pose_vertex])
        self._anchor_sigma = self.columns.joint(self.anchors)
        self.window.reset([pose_vertex.dimension])
        self._note_pose(pose_vertex)

    def add_pose(self, edge) -> None:
        """A new current pose, ``edge.vertex(1)``, predicted from the previous one by the odometry ``edge``."""
        t0 = time.perf_counter()
        check_pose_edge(edge, self.pose, self.graph, self.model)
        F, Q = motion_jacobians(edge)
        self.window.predict(F, Q)
        self.pose = edge.vertex(1)
        self._note_pose(self.pose)
        self.stats["pose_time"] += time.perf_counter() - t0

    def refresh(self, factors=FACTORISE) -> bool:
        """Factorise H at the graph's current estimates (structure built) and re-anchor the window. ``factors``:
        the caller's ``graph.hessian_factors()`` (None: H was not positive definite), when it has them — taken at
        the estimates it wants the covariances of. With ``verify_merges``, the merges made since the last refresh
        are first tested and the refused ones undone (``verification``)."""
        self._verify_pending_merges()
        t0 = time.perf_counter()
        roots = self.confirmed_tracks()
        survivors = [t for t in self.tracks if t.status == TENTATIVE]
        anchors = [self.pose]
        for t in survivors:
            if not any(t.parent is a for a in anchors):
                anchors.append(t.parent)
        if factors is FACTORISE:
            factors = hessian_factors(self.graph)
        columns = MarginalColumns()
        if not columns.refresh(self.graph, anchors + [t.vertex for t in roots], factors):
            return False
        self.columns, self.anchors, self._factorised = columns, anchors, roots
        self._anchor_sigma = columns.joint(anchors)          # the anchors' joint covariance, read every scan
        self._factorised_pos = np.array([t.vertex.estimate for t in roots]).reshape(-1, self.model.landmark_dimension)
        self.window.reset([a.dimension for a in anchors])
        for t in survivors:
            m, gx, gz = self.model.inverse(t.parent.estimate, t.z0)
            a = next(i for i, v in enumerate(anchors) if v is t.parent)
            self.window.add_independent(t.key, m, a, gx, gz @ t.R0 @ gz.T)
        self._pair_orphans(factors)
        self.stats["refreshes"] += 1
        self.stats["refresh_time"] += time.perf_counter() - t0
        return True

    # ================================================================================= the scan's problem
    def _widening(self):
        """(range, bearing) widening of the footprint for candidates: the model's margins plus n_σ times the
        position and heading standard deviations of the current pose."""
        P = self.window.pose_covariance(self._anchor_sigma)
        pos = float(largest_sd(P[None, :2, :2], check=False)[0])
        return (self.model.range_margin + self.n_sigma * pos,
                self.model.bearing_margin + self.n_sigma * float(np.sqrt(max(P[2, 2], 0.0))))

    def _candidates(self, x):
        """(window keys, factorised indices) of the candidate landmarks seen from pose x: one prediction of the
        window's means and the factorised landmarks together."""
        wkeys = self.window.keys
        nw = len(wkeys)
        if not nw and not len(self._factorised):
            return [], np.zeros(0, dtype=np.int64)
        points = self._factorised_pos
        if nw:
            points = np.vstack([np.array([self.window.means[k] for k in wkeys]).reshape(nw, -1), points])
        inside = self.model.candidates(x, points, self._widening())
        return [wkeys[i] for i in np.flatnonzero(inside[:nw])], np.flatnonzero(inside[nw:])

    def _density(self, x, wkeys, gidx, R):
        """(ŷ (k, d), joint covariance (d·k, d·k), R_k (k, d, d)) of the candidates in the association space —
        window items first, then factorised landmarks — and their state: Σ_v of [x; m_1 … m_k] and the means."""
        sigma = self.columns.joint(self.anchors + [self._factorised[i].vertex for i in gidx])
        sig_v = self.window.covariance(wkeys, sigma)
        means = self._factorised_pos[gidx]
        if wkeys:
            means = np.vstack([np.array([self.window.means[k] for k in wkeys]).reshape(-1, 2), means])
        yhat, C, Rk = self.model.scan_density(x, means, sig_v, R)
        return yhat, C, Rk, sig_v, means

    def _relative_sigma(self, x, means, sig_v, C, Rk):
        """``decisions.relative_sigma`` of the candidates. In the Cartesian association space ŷ_k is q_k itself,
        so the diagonal blocks of the density minus the noise, C_kk − R_k = J_k Σ_v J_kᵀ, are q_k's covariances."""
        if self.model.association_space != "cartesian":
            return relative_sigma(x, means, sig_v)
        return block_largest_sd(C, Rk)                     # largest_sd of the blocks, compiled

    def _associate(self, yhat, C, Y, R, cand, cand_tracks):
        """The algorithm on candidates ``cand`` (their tracks ``cand_tracks``) and all of Y; ambiguous pairings
        removed. Returns (idx over ``cand``, observations rejected as ambiguous, Association, d² (len(cand), m)
        of every candidate–observation pair)."""
        if len(cand) < len(yhat):
            yhat, C, _ = sub_problem(yhat, C, Y, cand, np.arange(Y.shape[1]))
        problem = problem_from_cov(yhat, C, Y, self.n_sigma)        # one problem for every run on this scan
        assoc = associate(self.algorithm, problem, None, self.n_sigma, self.options, R)
        idx = np.asarray(assoc.idx, dtype=np.int64).copy()
        rejected = []
        d2 = problem.ic_d2
        if self.reject_ambiguous:
            tentative = np.array([t.status == TENTATIVE for t in cand_tracks])
            for k in ambiguous_pairings(self.algorithm, problem, R, idx, self.options, tentative):
                rejected.append(int(idx[k]))
                idx[k] = -1
        self.stats["ambiguous_rejected"] += len(rejected)
        self.stats["nodes"] += int(assoc.stats.get("nodes", 0))
        self.stats["budget_exhausted"] += int(assoc.budget_exhausted)
        return idx, rejected, assoc, d2

    # ================================================================================= one scan
    def process_scan(self, Z, R, information=None) -> ScanResult:
        """Associate one scan of the current pose (module docstring). ``R`` is the observations' noise
        covariance, ``information`` the edges' Ω (default R⁻¹; (d, d) or one per observation). Z, R and Ω are
        checked before anything changes; a scan that raises part-way is undone (``scan_guard.ScanUndo``)."""
        t_scan = time.perf_counter()
        Z, R, information, noise = check_scan(self.model, Z, R, information, self._checked_noise)
        if self.pose is None:
            raise ValueError("process_scan: call start(first_pose) first")
        x = self.pose.estimate
        wkeys, gidx = self._candidates(x)
        cands = [self.tracks[k] for k in wkeys] + [self._factorised[i] for i in gidx]
        self._undo = ScanUndo(self, cands)
        try:
            result = self._scan(Z, R, information, x, wkeys, gidx, cands)
        except BaseException:
            self._undo.restore()
            raise
        finally:
            self._undo = None
        self._checked_noise = noise
        self.stats["scan_time"] += time.perf_counter() - t_scan
        return result

    def _scan(self, Z, R, information, x, wkeys, gidx, cands) -> ScanResult:
        """``process_scan`` once its arguments are checked and its undo recorded; the edges are added last."""
        m, scan = Z.shape[1], self.scan_count
        self.scan_count += 1
        result = ScanResult(m)
        result.candidates = [t.key for t in cands]
        obs0 = len(self.observation_log["key"])
        self._log(scan, m)
        edges, confirmable = [], []
        discard = np.zeros(m, dtype=bool)
        closure = None
        if cands and m:
            t0 = time.perf_counter()
            yhat, C, Rk, sig_v, means = self._density(x, wkeys, gidx, R)
            yu, Yu = self.model.association_observations(Z, yhat)
            Rgate = Rk[int(Rk.trace(axis1=1, axis2=2).argmax())]
            untrusted = (np.array([t.status == CONFIRMED for t in cands])
                         & (self._relative_sigma(x, means, sig_v, C, Rk) > self.closure_sigma))
            trusted = self._tracking_candidates(cands, untrusted)
            if trusted.size:
                idx, rejected, result.association, d2 = self._associate(yu, C, Yu, Rgate, trusted,
                                                                        [cands[i] for i in trusted])
                discard[rejected] = True
                if self._exclusion_gate is not None:
                    discard |= (d2 <= self._exclusion_gate).any(axis=0)
                for i, j in zip(trusted.tolist(), idx.tolist()):
                    self._outcome(cands[i], j, x, obs0, Z, information, scan, edges, confirmable, result)
            confirmable = self._merge_duplicates(confirmable, cands, trusted, untrusted, sig_v, means, scan, edges,
                                                 result)
            closure = (yu, C, Yu, Rgate, np.flatnonzero(untrusted), cands)
            self.stats["association_time"] += time.perf_counter() - t0
            self.stats["scans_associated"] += 1
            self.stats["candidates"] += len(cands)
        for j in np.flatnonzero((result.labels < 0) & discard).tolist():
            self._pool(self.pose, Z[:, j], information[j], obs0 + j)
        for j in np.flatnonzero((result.labels < 0) & ~discard):
            t = self._new_track(x, int(j), Z[:, j], R, information[j], obs0 + int(j), scan, result)
            if self.rules.n_confirm == 1:
                confirmable.append((t, int(j)))
        self._closure_stage(confirmable, closure, scan, edges, result)
        self._expire(scan, result)
        self.observation_log["key"][obs0:obs0 + m] = result.labels.tolist()
        if edges:                       # last: add_edges checks everything before it adds anything
            self.graph.add_edges(self.model.edge_class, [(p, v) for p, v, _, _ in edges],
                                 np.array([e[2] for e in edges]), np.array([e[3] for e in edges]))
        return result

    def _outcome(self, t, j, x, obs0, Z, information, scan, edges, confirmable, result):
        """Candidate t after the tracking stage: paired with column j (≥ 0), or missed."""
        if j >= 0:
            result.labels[j] = t.key
            t.observations.append(obs0 + j)
            t.hits += 1
            t.misses = 0
            if t.status == CONFIRMED:
                edges.append((self.pose, t.vertex, Z[:, j], information[j]))
                return
            t.pending.append((self.pose, Z[:, j].copy(), information[j], obs0 + j))
            if t.hits >= self.rules.n_confirm:
                confirmable.append((t, j))
        elif t.status == TENTATIVE and self._expected(x, t):
            t.misses += 1
            if t.misses >= self.rules.n_miss:
                self._drop(t, scan, result)

    def _expected(self, x, t) -> bool:
        """Whether tentative landmark t is predicted inside the nominal footprint (so it should have been seen)."""
        zhat = self.model.predict(x, self.window.means[t.key][None], jacobians=False)[0]
        return bool(self.model.in_footprint(zhat, (0.0, 0.0))[0])

    def _log(self, scan, m):
        self.observation_log["scan"].extend([scan] * m)
        self.observation_log["column"].extend(range(m))
        self.observation_log["key"].extend([-1] * m)

    # ================================================================================= track decisions
    def _confirm(self, t, scan, edges, result):
        vertex = self.landmark_factory(t.key, self.window.means[t.key])
        self.graph.add_vertex(vertex)
        if self._undo is not None:
            self._undo.vertices.append(vertex)  # removed again if the scan fails
        self._attach(t, vertex, scan, edges)
        result.confirmed.append(t.key)

    def _merge(self, t, old, scan, edges, result):
        """Loop closure: t's observations become edges to the vertex of the old landmark ``old``."""
        if old.alias_of >= 0:                      # a merged track stands for its old landmark
            old = self.tracks[old.alias_of]
        t.alias_of = old.key
        self._attach(t, old.vertex, scan, edges)
        result.merged.append((t.key, old.key))
        self._note_merge(t, old, scan)
        self.stats["merges"] += 1

    def _attach(self, t, vertex, scan, edges):
        t.vertex, t.status, t.end, t.postponed_since = vertex, CONFIRMED, scan, -1
        for pose, z, info, _ in t.pending:
            edges.append((pose, vertex, z, info))
        t.pending = []

    def _drop(self, t, scan, result):
        for pose, z, info, obs in t.pending:
            self._pool(pose, z, info, obs)
        self.window.remove(t.key)
        t.status, t.end, t.pending = DROPPED, scan, []
        result.dropped.append(t.key)

    def _new_track(self, x, j, z, R, info, obs, scan, result):
        key = len(self.tracks)
        mean, gx, gz = self.model.inverse(x, z)
        self.window.add_landmark(key, mean, gx, gz, R)
        t = Track(key=key, birth=scan, parent=self.pose, z0=z.copy(), R0=R.copy(),
                  pending=[(self.pose, z.copy(), info, obs)], observations=[obs])
        self.tracks.append(t)
        result.labels[j] = key
        result.new.append(key)
        return t

    def _expire(self, scan, result):
        """Drop the tentative landmarks that waited too long. Every tentative track is in the window (a new track
        enters it, a refresh re-enters the survivors, a drop removes it), so only the window's are visited."""
        for key in sorted(self.window.keys):
            t = self.tracks[key]
            if t.status != TENTATIVE:
                continue
            if t.postponed_since >= 0:
                if scan - t.postponed_since >= self.closure_patience:
                    self._drop(t, scan, result)
            elif self.rules.max_age is not None and scan - t.birth >= self.rules.max_age:
                self._drop(t, scan, result)

    # ================================================================================= results
    def confirmed_tracks(self):
        """The confirmed landmarks that own a vertex (merged tracks excluded), in creation order."""
        return [t for t in self.tracks if t.status == CONFIRMED and t.alias_of < 0]

    def observation_assignment(self) -> np.ndarray:
        """For every observation processed: the key of the landmark (vertex owner) it is an edge of, or −1
        (discarded, or its tentative landmark was dropped or is still tentative)."""
        keys = np.asarray(self.observation_log["key"], dtype=np.int64)
        root = np.array([(t.alias_of if t.alias_of >= 0 else t.key) if t.status == CONFIRMED else -1
                         for t in self.tracks] + [-1], dtype=np.int64)
        return root[np.where(keys >= 0, keys, len(self.tracks))]
