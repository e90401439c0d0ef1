"""Late association: observations the front-end left out are paired after an optimisation, when the map says where
they belong.

The front-end decides each scan from the estimate it has at that moment, and it leaves some observations out of
the map:

- the observations of a tentative landmark that is **dropped** (not re-observed, or too old) — on Victoria Park,
  often the first sightings of a tree whose landmark is confirmed later from a new track;
- observations **discarded** in the tracking stage: inside the exclusion gate of a candidate without being paired
  with it, or with an equally good alternative (``decisions.ambiguous_pairings``).

With ``late_association`` on, each of them is kept in a pool — its pose vertex, measurement z and the information Ω
of the edge it would become (R = Ω⁻¹ below) — instead of being forgotten. After every optimisation (``refresh``)
each pooled observation is tested against the confirmed landmarks near it, at the graph's new estimates. For
landmark l and the observation's pose x, with ẑ = h(x, m_l), the edge's Jacobians H = [H_x H_m] and Σ the joint
marginal covariance of (x, m_l) from the factorisation the refresh already made (``covariance.MarginalColumns``,
only these vertices' columns),

    ν = z − ẑ  (bearing wrapped),   S = H Σ Hᵀ + R,   d² = νᵀ S⁻¹ ν.

The observation is paired with l — a range-bearing edge from its pose to l's vertex — when d² is inside the late
gate (χ²_d at ``late_n_sigma``) and no other landmark is inside the exclusion gate (χ²_d at
``rules.exclusion_n_sigma``, or the late gate when that is wider or None). The late gate is narrower than the
tracking gate (default 2σ): a late decision is never revisited. On Victoria Park's tuned setting the right late
pairings have d² below 2, while a 4σ gate also let through wrong ones with d² up to 17, and they collapsed the run
(``benchmarks/RESULTS.md``). A pooled observation that pairs with nothing stays in the pool and is tested again
after the next optimisation. Only landmarks within ``late_radius`` metres of its inverse observation are tested: a
cheap Euclidean pre-selection before any covariance is formed.

**Unmapped landmarks.** Pooled observations that no landmark explains may be one landmark the front-end never
confirmed: a tree whose sightings were too far apart for its tentative landmark to survive ``n_miss`` or
``max_age``. After the pairing, the orphans that no landmark holds inside the exclusion gate are grouped around each
orphan (those within ``late_radius`` / 2 of its inverse observation, one per pose: a scan sees a landmark once). A
group of at least ``rules.n_confirm`` passes when one point explains all of it (``group_test``: χ² of the inverse
observations about their weighted mean, on their joint covariance with the poses' cross-covariances, against
χ²_{d(n−1)} at ``late_n_sigma``); while it fails, the member with the largest normalised residual is removed. A
group that passes becomes a confirmed landmark, each of its observations an edge to it — the confirmation rule
applied with hindsight: ``n_confirm`` consistent observations, from the scans received so far.

A tentative landmark is still dropped as the rule says; its observations only ever reach the map through a
landmark that a later test confirms.
"""
from __future__ import annotations

import numpy as np

from ...gaussian import chi2inv, confidence_level
from ...graph import wrap_angle
from ...validation import boolean, positive_number
from .covariance import MarginalColumns
from .tracks import CONFIRMED, Track

__all__ = ["LateAssociation", "group_test", "innovation_d2"]


def innovation_d2(model, x, landmark, z, sigma, R) -> float:
    """d² = νᵀ(H Σ Hᵀ + R)⁻¹ν of measurement z from pose x of landmark ``landmark`` (module docstring); ``sigma``
    is the joint covariance of (x, landmark) (5 × 5 for a 2-D pose and point), ``R`` the measurement noise."""
    zhat, hx, hm = model.predict(x, np.asarray(landmark, dtype=float)[None])
    nu = np.asarray(z, dtype=float) - zhat[0]
    for i in model.angular:
        nu[i] = wrap_angle(nu[i])
    H = np.hstack([hx[0], hm[0]])
    S = H @ sigma @ H.T + R
    return float(nu @ np.linalg.solve(0.5 * (S + S.T), nu))


class LateAssociation:
    """Mixin of ``OnlineFrontEnd``: the pool of left-out observations and their pairing after each refresh."""

    def _init_late(self, late_association, late_n_sigma, late_radius):
        self.late_association = boolean(late_association, "late_association")
        self.late_radius = positive_number(late_radius, "late_radius")
        self.late_n_sigma = positive_number(late_n_sigma, "late_n_sigma")
        self._late_gate = float(chi2inv(confidence_level(self.late_n_sigma), self.model.dimension))
        self.orphans = []               # [(pose vertex, z, information, observation number)]
        self.stats["late_paired"] = 0
        self.stats["late_landmarks"] = 0
        self.late_log = []              # [(observation number, landmark key, d², scan count at the pairing)]

    def _pool(self, pose, z, info, obs) -> None:
        """Keep a left-out observation for later (nothing when late association is off)."""
        if self.late_association:
            self.orphans.append((pose, np.array(z, dtype=float), np.array(info, dtype=float), obs))

    def _late_candidates(self, points):
        """[(orphan index, [root tracks within late_radius])] at the current estimates; ``points`` (n, 2) are the
        orphans' inverse observations."""
        roots = [t for t in self.tracks if t.status == CONFIRMED and t.alias_of < 0]
        if not roots or not len(points):
            return []
        pos = np.array([t.vertex.estimate for t in roots])
        dist = np.hypot(points[:, None, 0] - pos[None, :, 0], points[:, None, 1] - pos[None, :, 1])
        return [(i, [roots[k] for k in np.flatnonzero(row <= self.late_radius).tolist()])
                for i, row in enumerate(dist) if (row <= self.late_radius).any()]

    def _cluster_seeds(self, points, blocked):
        """Groups of pooled observations that may be one unmapped landmark: for each orphan (oldest first) not in
        ``blocked``, itself and the unblocked orphans of other poses within ``late_radius`` / 2 of it, when they
        are at least ``rules.n_confirm``."""
        n = len(points)
        near = np.hypot(points[:, None, 0] - points[None, :, 0], points[:, None, 1] - points[None, :, 1])
        near = near <= 0.5 * self.late_radius
        near[list(blocked), :] = False
        near[:, list(blocked)] = False
        out = []
        for i in range(n):
            group, poses = [], set()
            for j in np.flatnonzero(near[i]).tolist():
                if id(self.orphans[j][0]) not in poses:         # one observation per pose: one scan sees a tree once
                    poses.add(id(self.orphans[j][0]))
                    group.append(j)
            if len(group) >= self.rules.n_confirm:
                out.append(group)
        return out

    def _pair_orphans(self, factors) -> int:
        """Test the pool against the confirmed landmarks, then for unmapped landmarks (module docstring), with the
        refresh's ``factors``; add the edges and landmarks, and remove what was used from the pool. Returns the
        number of observations placed."""
        if not self.late_association or not self.orphans:
            return 0
        points = np.array([self.model.inverse(p.estimate, z)[0] for p, z, _, _ in self.orphans])
        todo = self._late_candidates(points)
        seeds = self._cluster_seeds(points, set())
        if not todo and not seeds:
            return 0
        vertices = {}
        for i, ts in todo:
            for v in [self.orphans[i][0]] + [t.vertex for t in ts]:
                vertices[id(v)] = v
        for group in seeds:
            for j in group:
                vertices[id(self.orphans[j][0])] = self.orphans[j][0]
        columns = MarginalColumns()
        if not columns.refresh(self.graph, list(vertices.values()), factors):
            return 0
        used, blocked = self._pair_with_landmarks(todo, columns)
        placed = len(used)
        for group in self._cluster_seeds(points, used | blocked):
            if not used.isdisjoint(group):
                continue
            members = self._consistent_group(group, columns)
            if members:
                self._new_landmark(members)
                used.update(members)
                placed += len(members)
        if used:
            self.orphans = [o for i, o in enumerate(self.orphans) if i not in used]
        return placed

    def _pair_with_landmarks(self, todo, columns):
        """The pairing test of every orphan against its nearby landmarks; returns (paired orphans, orphans with a
        landmark inside the exclusion gate that were not paired — they cannot start a landmark either)."""
        gate = self._late_gate
        exclusion = gate if self._exclusion_gate is None else max(self._exclusion_gate, gate)
        rows, paired, blocked = [], set(), set()
        for i, ts in todo:
            pose, z, info, obs = self.orphans[i]
            R = np.linalg.inv(info)
            d2 = np.array([innovation_d2(self.model, pose.estimate, t.vertex.estimate, z,
                                         columns.joint([pose, t.vertex]), R) for t in ts])
            best = int(np.argmin(d2))
            if d2[best] <= gate and np.count_nonzero(d2 <= exclusion) == 1:
                t = ts[best]
                rows.append((pose, t.vertex, z, info))
                self.observation_log["key"][obs] = t.key
                t.observations.append(obs)
                self.late_log.append((obs, t.key, float(d2[best]), self.scan_count))
                paired.add(i)
            elif d2[best] <= exclusion:
                blocked.add(i)
        if rows:
            self._add_rows(rows)
            self.stats["late_paired"] += len(rows)
        return paired, blocked

    def _add_rows(self, rows):
        self.graph.add_edges(self.model.edge_class, [(p, v) for p, v, _, _ in rows],
                             np.array([r[2] for r in rows]), np.array([r[3] for r in rows]))

    def _consistent_group(self, group, columns):
        """The largest consistent subset of ``group`` (at least ``rules.n_confirm`` orphans), removing the worst
        member while the group test fails (``group_test``); [] when none is left."""
        members = list(group)
        while len(members) >= self.rules.n_confirm:
            items = [self.orphans[j] for j in members]
            sigma = columns.joint([o[0] for o in items])
            ok, _, worst = group_test(self.model, items, sigma, self.late_n_sigma)
            if ok:
                return members
            members.pop(worst)
        return []

    def _new_landmark(self, members):
        """A confirmed landmark from pooled observations: its vertex starts at the mean of their inverse
        observations (the next optimisation moves it), and each of them becomes an edge to it."""
        items = [self.orphans[j] for j in members]
        first = items[0]
        key = len(self.tracks)
        mean = np.mean([self.model.inverse(p.estimate, z)[0] for p, z, _, _ in items], axis=0)
        vertex = self.landmark_factory(key, mean)
        self.graph.add_vertex(vertex)
        t = Track(key=key, birth=self.observation_log["scan"][first[3]], parent=first[0], z0=first[1],
                  R0=np.linalg.inv(first[2]), status=CONFIRMED, observations=[o[3] for o in items],
                  hits=len(items), vertex=vertex, end=self.scan_count)
        self.tracks.append(t)
        for _, _, _, obs in items:
            self.observation_log["key"][obs] = key
        self._add_rows([(p, vertex, z, info) for p, z, info, _ in items])
        self.stats["late_landmarks"] += 1
        self.late_log.extend((obs, key, float("nan"), self.scan_count) for _, _, _, obs in items)


def group_test(model, items, sigma, n_sigma):
    """Whether pooled observations ``items`` [(pose vertex, z, Ω, obs)] (distinct poses) can be one landmark.

    The inverse observations p_i = g(x_i, z_i) have the joint covariance C = G_x Σ G_xᵀ + blkdiag(G_z,i R_i G_z,iᵀ)
    (Σ the poses' joint covariance ``sigma``, R_i = Ω_i⁻¹). One landmark m explains them all when

        χ² = min_m (p − A m)ᵀ C⁻¹ (p − A m) ≤ χ²_{d(n−1)} at ``n_sigma``,   A = [I; I; …; I],

    m̂ = (AᵀC⁻¹A)⁻¹ AᵀC⁻¹ p. Returns (passed, m̂, index of the member with the largest normalised residual).
    """
    n, d = len(items), model.landmark_dimension
    p, Gx, Cz = np.zeros(n * d), np.zeros((n * d, sigma.shape[0])), np.zeros((n * d, n * d))
    col = 0
    for i, (pose, z, info, _) in enumerate(items):
        m, gx, gz = model.inverse(pose.estimate, z)
        r = slice(d * i, d * i + d)
        p[r] = m
        k = pose.dimension
        Gx[r, col:col + k] = gx
        col += k
        Cz[r, r] = gz @ np.linalg.inv(info) @ gz.T
    C = Gx @ sigma @ Gx.T + Cz
    A = np.tile(np.eye(d), (n, 1))
    Ci = np.linalg.inv(0.5 * (C + C.T))
    m_hat = np.linalg.solve(A.T @ Ci @ A, A.T @ Ci @ p)
    res = p - A @ m_hat
    chi2 = float(res @ Ci @ res)
    w = (Ci @ res).reshape(n, d) * res.reshape(n, d)
    gate = float(chi2inv(confidence_level(n_sigma), d * (n - 1)))
    return chi2 <= gate, m_hat, int(np.argmax(w.sum(axis=1)))
