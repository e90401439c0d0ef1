"""What has happened since the last factorisation: the current pose and the new landmarks, as linear functions
of a few factorised vertices plus independent noise.

Between two factorisations of H the graph grows (one pose per tick, new landmarks, new edges) but its
covariance is not recomputed. The window keeps, for every quantity y that the factorisation does not cover —
the newest pose x, and the landmarks created since (tentative or just confirmed) — the linearised form

    y = ŷ + A δa + e,     δa ~ N(0, Σ_aa) (the *anchors*: vertices of the factorisation),
                          e  ~ N(0, P_e), independent of everything the factorisation covers,

because e is made of the odometry and measurement noise of edges added after the factorisation. Then

    Cov(y) = A Σ_aa Aᵀ + P_e,    Cov(y, ℓ) = A Σ_aℓ  for a factorised landmark ℓ.

Operations (x is always the first item, 3 rows):

- ``reset(anchor)``: x = the anchor pose itself (A = I, e = 0), no other items;
- ``predict(F, Q)``: x' = F x + n, Cov(n) = Q — A_x ← F A_x, P_e ← T P_e Tᵀ + blkdiag(Q, 0), T = blkdiag(F, I);
- ``add_landmark(key, m̂, G_x, G_z, R)``: m = g(x, z) linearised, A_m = G_x A_x, e_m = G_x e_x + G_z v, so
  P_mm = G_x P_xx G_xᵀ + G_z R G_zᵀ and P_m· = G_x P_x·;
- ``add_independent(key, m̂, anchor_index, G_x, P)``: a landmark that is a function of one anchor pose plus its
  own noise (a tentative landmark carried over a factorisation, re-derived from the pose that first saw it);
- ``remove(key)``.

Observations of window landmarks are *not* fused (no update step): the window's covariances are those of the
prediction alone, which is conservative (never smaller than the truth) until the next factorisation, where the
optimiser fuses everything.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["LocalWindow"]


class LocalWindow:
    """The linear-Gaussian bookkeeping of the module docstring. ``anchor_dims``: dimensions of the anchors."""

    def __init__(self):
        self.anchor_dims = []
        self.A = np.zeros((3, 0))
        self.P = np.zeros((3, 3))
        self.means = {}
        self.rows = {}
        self._order = []

    # ------------------------------------------------------------------------------------------- structure
    def reset(self, anchor_dims, pose_anchor: int = 0):
        """Anchors of dimensions ``anchor_dims``; x is anchor ``pose_anchor`` itself."""
        self.anchor_dims = [int(d) for d in anchor_dims]
        self.A = np.zeros((3, sum(self.anchor_dims)))
        start = self._anchor_offset(pose_anchor)
        self.A[:, start:start + 3] = np.eye(3)
        self.P = np.zeros((3, 3))
        self.means, self.rows, self._order = {}, {}, []

    def _anchor_offset(self, i):
        return int(sum(self.anchor_dims[:i]))

    @property
    def keys(self):
        return list(self._order)

    def __contains__(self, key):
        return key in self.rows

    def _append(self, key, mean, A_rows, P_cross, P_self):
        if key in self.rows:
            raise ValueError(f"key: {key!r} is already in the window")
        r = self.P.shape[0]
        dim = len(mean)
        P = np.zeros((r + dim, r + dim))
        P[:r, :r] = self.P
        P[r:, :r] = P_cross
        P[:r, r:] = P_cross.T
        P[r:, r:] = 0.5 * (P_self + P_self.T)
        self.P = P
        self.A = np.vstack([self.A, A_rows])
        self.rows[key] = r
        self.means[key] = np.asarray(mean, dtype=float).copy()
        self._order.append(key)

    # ------------------------------------------------------------------------------------------- operations
    def predict(self, F, Q):
        """x' = F x + n with Cov(n) = Q: ``predict_reference``'s numbers from one compiled call (it runs every tick;
        ``_predict`` below, tested equal to the reference)."""
        F, Q = np.ascontiguousarray(F, dtype=float), np.ascontiguousarray(Q, dtype=float)
        if F.shape != (3, 3) or Q.shape != (3, 3):
            raise ValueError(f"F and Q must be (3, 3), got {F.shape} and {Q.shape}")
        _predict(self.A, self.P, F, Q)

    def predict_reference(self, F, Q):
        """x' = F x + n with Cov(n) = Q, in numpy: A_x ← F A_x, P_e ← T P_e Tᵀ + blkdiag(Q, 0), T = blkdiag(F, I)."""
        self.A[:3] = F @ self.A[:3]
        self.P[:3, :] = F @ self.P[:3, :]
        self.P[:, :3] = self.P[:, :3] @ F.T
        self.P[:3, :3] += Q
        self.P[:3, :3] = 0.5 * (self.P[:3, :3] + self.P[:3, :3].T)

    def add_landmark(self, key, mean, Gx, Gz, R):
        """m = g(x, z) for the current pose x and an observation with noise covariance R."""
        P_cross = Gx @ self.P[:3, :]
        P_self = Gx @ self.P[:3, :3] @ Gx.T + Gz @ R @ Gz.T
        self._append(key, mean, Gx @ self.A[:3], P_cross, P_self)

    def add_independent(self, key, mean, anchor: int, Gx, P_self):
        """m = ŷ + G_x δa_anchor + e_m with Cov(e_m) = P_self, e_m independent of the other items."""
        A_rows = np.zeros((len(mean), self.A.shape[1]))
        s = self._anchor_offset(anchor)
        A_rows[:, s:s + Gx.shape[1]] = Gx
        self._append(key, mean, A_rows, np.zeros((len(mean), self.P.shape[0])), P_self)

    def remove(self, key):
        r = self.rows.pop(key)
        dim = len(self.means.pop(key))
        self._order.remove(key)
        keep = np.r_[0:r, r + dim:self.P.shape[0]]
        self.P = self.P[np.ix_(keep, keep)]
        self.A = self.A[keep]
        for k in self._order:
            if self.rows[k] > r:
                self.rows[k] -= dim

    # ------------------------------------------------------------------------------------------- queries
    def item_rows(self, keys):
        """Row indices of x followed by the items ``keys`` (in that order)."""
        if not keys:
            return np.arange(3)
        rows = [np.arange(3)]
        for k in keys:
            r = self.rows[k]
            rows.append(np.arange(r, r + len(self.means[k])))
        return np.concatenate(rows)

    def pose_covariance(self, sigma):
        """Covariance (3, 3) of the current pose x = A_x a + n_x from ``sigma``, the joint covariance of the
        anchors (``covariance(keys=[])`` restricted to x, without the other items)."""
        return _covariance(self.A, self.P, np.arange(3), self._sigma(sigma))

    def _sigma(self, sigma):
        """``sigma`` as a square float array that starts with the anchors' rows, else ValueError."""
        sigma = np.ascontiguousarray(sigma, dtype=float)
        na = self.A.shape[1]
        if sigma.ndim != 2 or sigma.shape[0] != sigma.shape[1] or sigma.shape[0] < na:
            raise ValueError(f"sigma must be a square covariance of the {na} anchor rows (and others), got shape "
                             f"{sigma.shape}")
        return sigma

    def covariance(self, keys, sigma):
        """Joint covariance of [x; items ``keys``; other factorised vertices o] from ``sigma``, the joint
        covariance of [anchors; o] of the factorisation (anchors in ``reset`` order): ``covariance_reference``'s
        numbers from one compiled call (``_covariance``; the front-end asks for it on every scan)."""
        return _covariance(self.A, self.P, self.item_rows(keys), self._sigma(sigma))

    def covariance_reference(self, keys, sigma):
        """``covariance`` in numpy: [[A Σ_aa Aᵀ + P_e, A Σ_ao], [Σ_oa, Σ_oo]] for the rows of x and ``keys``."""
        na = self.A.shape[1]
        rows = self.item_rows(keys)
        A = self.A[rows]
        k = len(rows)
        q = sigma.shape[0] - na
        out = np.empty((k + q, k + q))
        out[:k, :k] = A @ sigma[:na, :na] @ A.T + self.P[rows][:, rows]
        cross = A @ sigma[:na, na:]
        out[:k, k:] = cross
        out[k:, :k] = cross.T
        out[k:, k:] = sigma[na:, na:]
        return 0.5 * (out + out.T)


@njit(cache=True)
def _predict(A, P, F, Q):
    """``LocalWindow.predict_reference`` in place: the rows of x in A and P become F times themselves, the columns of
    x in P times Fᵀ, then P_xx gains Q and is symmetrised."""
    na, n = A.shape[1], P.shape[0]
    row = np.empty(max(na, n))
    tmp = np.empty((3, max(na, n)))
    for a in range(3):                                  # A_x ← F A_x
        for c in range(na):
            tmp[a, c] = F[a, 0] * A[0, c] + F[a, 1] * A[1, c] + F[a, 2] * A[2, c]
    A[:3, :na] = tmp[:, :na]
    for a in range(3):                                  # P[x, :] ← F P[x, :]
        for c in range(n):
            tmp[a, c] = F[a, 0] * P[0, c] + F[a, 1] * P[1, c] + F[a, 2] * P[2, c]
    P[:3, :] = tmp[:, :n]
    for r in range(n):                                  # P[:, x] ← P[:, x] Fᵀ
        for a in range(3):
            row[a] = P[r, 0] * F[a, 0] + P[r, 1] * F[a, 1] + P[r, 2] * F[a, 2]
        P[r, 0], P[r, 1], P[r, 2] = row[0], row[1], row[2]
    for a in range(3):
        for b in range(3):
            P[a, b] += Q[a, b]
    for a in range(3):
        for b in range(a + 1, 3):
            v = 0.5 * (P[a, b] + P[b, a])
            P[a, b] = v
            P[b, a] = v


@njit(cache=True)
def _covariance(A, P, rows, sigma):
    """``LocalWindow.covariance_reference``: with A_r = A[rows], the blocks A_r Σ_aa A_rᵀ + P[rows, rows] and
    A_r Σ_ao (both from T = A_r Σ[:na, :]), Σ_oo, then ½(C + Cᵀ)."""
    na, k, n = A.shape[1], rows.size, sigma.shape[0]
    q = n - na
    T = np.zeros((k, n))
    for i in range(k):
        for j in range(na):
            a = A[rows[i], j]
            if a != 0.0:
                for c in range(n):
                    T[i, c] += a * sigma[j, c]
    out = np.empty((k + q, k + q))
    for i in range(k):
        for e in range(k):
            s = 0.0
            for j in range(na):
                s += T[i, j] * A[rows[e], j]
            out[i, e] = s + P[rows[i], rows[e]]
        for c in range(q):
            out[i, k + c] = T[i, na + c]
            out[k + c, i] = T[i, na + c]
    for c in range(q):
        for e in range(q):
            out[k + c, k + e] = sigma[na + c, na + e]
    for i in range(k + q):
        for e in range(i + 1, k + q):
            v = 0.5 * (out[i, e] + out[e, i])
            out[i, e] = v
            out[e, i] = v
    return out
