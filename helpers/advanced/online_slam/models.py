"""The measurement and motion models the front-end needs, read from the graph's own edge classes.

Measurement model (``RangeBearingModel``, the laser of DriveBot and the tree detector of Victoria Park). The
front-end never writes an equation of its own for the prediction: the edge class gives it. With the convention
e = h(x, m) − z of ``helpers.graph``, evaluating the edge at z = 0 returns the prediction h(x, m) itself, and the
edge's Jacobians are ∂h/∂x and ∂h/∂m:

    ẑ = h(x, m) = [‖m − p‖, wrap(atan2(m_y − y, m_x − x) − ψ)],   H_x = ∂h/∂x (2×3),   H_m = ∂h/∂m (2×2).

The one thing an edge class cannot give is the inverse observation that places a new landmark,

    m = g(x, z) = p + z_r [cos(z_β + ψ), sin(z_β + ψ)],   G_x = ∂g/∂x (2×3),   G_z = ∂g/∂z (2×2),

so the model class holds it, together with the sensor footprint (range and field of view) that decides which
landmarks are candidates.

Motion (``motion_jacobians``): any binary pose–pose edge e(x_k, x_{k+1}, z) with information Ω gives, linearised,
0 = e₀ + J_k δx_k + J_{k+1} δx_{k+1} + w (w ~ N(0, Ω⁻¹)), so the new pose is a linear function of the old one plus
noise:

    δx_{k+1} = F δx_k + n,   F = −J_{k+1}⁻¹ J_k,   Cov(n) = Q = J_{k+1}⁻¹ Ω⁻¹ J_{k+1}⁻ᵀ.

This holds for DriveBot's velocity-form kinematics edge (Q = ΔT² M R_odo Mᵀ) and for the relative-pose
``EdgeSE2`` of Victoria Park alike; J_{k+1} is invertible for both.

Association space (``association_space``). The edges in the graph are always range-bearing, but the innovations
the association algorithms compare can be formed in either of two spaces:

- ``"cartesian"`` (default): the landmark in the vehicle frame, q = R(ψ)ᵀ(m − p) (the model of
  ``EdgeSE2PointXY``, evaluated at z = 0), against each observation converted to q = z_r [cos z_β, sin z_β]
  with noise G R Gᵀ, G = ∂q/∂z, evaluated at the landmark's predicted range and bearing. q is *linear* in the
  vehicle position, so a large position error at a loop closure (metres, at a 10 m sensor range) leaves the
  predicted constellation rigid; in range-bearing a landmark's bearing and the bearing *differences* between
  landmarks change nonlinearly with that error, and joint compatibility rejects the right hypothesis
  (measured on DriveBot q2_b seed 2: recall 0.75 with range-bearing innovations, the loop never closes).
- ``"polar"``: ẑ = h(x, m) of the range-bearing edge and the raw observations. The L09 algorithms form
  innovations y − μ without wrapping, so ``unwrap_bearings`` first maps every bearing of the scan (predicted
  and observed) into one interval whose cut lies in the largest empty arc between them: a difference of two
  mapped bearings is then the wrapped difference unless the pair lies on both sides of that arc — which only a
  pairing that no gate would accept can do.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...graph import EdgeRangeBearing, EdgeSE2PointXY, wrap_angle
from ...validation import positive_number
from . import scan_kernels

__all__ = ["RangeBearingModel", "motion_jacobians", "unwrap_bearings"]


class RangeBearingModel:
    """Range-bearing observations of 2-D point landmarks from SE(2) poses (``EdgeRangeBearing``).

    Parameters
    ----------
    max_range : the sensor's range (m); landmarks predicted farther are not candidates.
    field_of_view : total angular width (rad) centred on the heading; 2π (default) is a 360° sensor.
    range_margin, bearing_margin : how far outside the footprint a predicted landmark still counts as a
        candidate (uncertainty: a landmark predicted at 10.3 m may be measured at 9.9 m); the front-end adds
        n_σ times the pose's position and heading standard deviations.
    association_space : "cartesian" (default) or "polar" (module docstring).
    """

    edge_class = EdgeRangeBearing
    dimension = 2
    landmark_dimension = 2
    angular = (1,)

    def __init__(self, max_range: float, field_of_view: float = 2.0 * math.pi, range_margin: float = 1.0,
                 bearing_margin: float = 0.1, association_space: str = "cartesian"):
        if association_space not in ("cartesian", "polar"):
            raise ValueError(f"association_space must be 'cartesian' or 'polar', got {association_space!r}")
        self.association_space = association_space
        self.max_range = positive_number(max_range, "max_range")
        self.field_of_view = positive_number(field_of_view, "field_of_view")
        if self.field_of_view > 2.0 * math.pi + 1e-12:
            raise ValueError(f"field_of_view must be at most 2π (a full turn), got {field_of_view!r}")
        self.range_margin = _non_negative(range_margin, "range_margin")
        self.bearing_margin = _non_negative(bearing_margin, "bearing_margin")

    def __repr__(self):
        return (f"RangeBearingModel(max_range={self.max_range}, field_of_view={self.field_of_view:.4f}, "
                f"range_margin={self.range_margin}, bearing_margin={self.bearing_margin}, "
                f"association_space={self.association_space!r})")

    def predict(self, x, landmarks, jacobians=True):
        """ẑ (k, 2) and, if asked, H_x (k, 2, 3), H_m (k, 2, 2) of the k landmarks (k, 2) seen from pose x (3,)."""
        landmarks = np.asarray(landmarks, dtype=float).reshape(-1, 2)
        k = landmarks.shape[0]
        states = [np.broadcast_to(np.asarray(x, dtype=float), (k, 3)).copy(), landmarks]
        zhat, jac = self.edge_class.evaluate(states, np.zeros((k, 2)), {}, jacobians=jacobians)
        if not jacobians:
            return zhat, None, None
        return zhat, jac[0], jac[1]

    def association_terms(self, x, landmarks, R):
        """(ŷ (k, d), H_x (k, d, 3), H_m (k, d, 2), R_k (k, d, d)): each landmark's predicted observation in the
        association space, its Jacobians and the observation noise there (module docstring)."""
        landmarks = np.asarray(landmarks, dtype=float).reshape(-1, 2)
        k = landmarks.shape[0]
        if self.association_space == "polar":
            zhat, hx, hm = self.predict(x, landmarks)
            return zhat, hx, hm, np.broadcast_to(R, (k, 2, 2)).copy()
        states = [np.broadcast_to(np.asarray(x, dtype=float), (k, 3)).copy(), landmarks]
        q, jac = EdgeSE2PointXY.evaluate(states, np.zeros((k, 2)), {}, jacobians=True)
        G = _polar_jacobian(np.hypot(q[:, 0], q[:, 1]), np.arctan2(q[:, 1], q[:, 0]))
        return q, jac[0], jac[1], G @ R @ G.transpose(0, 2, 1)

    def scan_density(self, x, means, sig_v, R):
        """(ŷ (k, d), C (d·k, d·k), R_k (k, d, d)): the k landmarks ``means`` (k, 2) predicted from pose x in the
        association space, and their joint covariance C = J Σ_v Jᵀ + blockdiag(R_k), where Σ_v is the joint
        covariance of [x; m_1 … m_k] and J = ∂ŷ/∂[x; m_1 … m_k] (``scan_density_reference``). In the Cartesian
        space the numbers come from one compiled loop (``scan_kernels.cartesian_density``), else from the
        reference."""
        x, means = _pose(x), _points(means, "means")
        sig_v, R = np.ascontiguousarray(sig_v, dtype=float), np.ascontiguousarray(R, dtype=float)
        n = 3 + 2 * len(means)
        if sig_v.shape != (n, n) or R.shape != (2, 2):
            raise ValueError(f"sig_v must be ({n}, {n}) and R (2, 2) for {len(means)} landmarks, got {sig_v.shape} "
                             f"and {R.shape}")
        if self.association_space != "cartesian":
            return self.scan_density_reference(x, means, sig_v, R)
        return scan_kernels.cartesian_density(x, means, sig_v, R)

    def scan_density_reference(self, x, means, sig_v, R):
        """``scan_density`` in numpy: ``association_terms`` gives ŷ, H_x, H_m and R_k; J stacks H_x (all rows)
        beside the block diagonal of the H_m."""
        yhat, hx, hm, Rk = self.association_terms(x, means, R)
        k, d, ld = len(yhat), self.dimension, self.landmark_dimension
        ar = np.arange(k)
        jm = np.zeros((k, d, k, ld))
        jm[ar, :, ar, :] = hm
        noise = np.zeros((k, d, k, d))
        noise[ar, :, ar, :] = Rk
        J = np.hstack([hx.reshape(d * k, 3), jm.reshape(d * k, ld * k)])
        C = J @ sig_v @ J.T + noise.reshape(d * k, d * k)
        return yhat, 0.5 * (C + C.T), Rk

    def association_observations(self, Z, yhat):
        """(ŷ, Y): the predictions and the observations Z (d, m), made comparable in the association space."""
        if self.association_space == "polar":
            return unwrap_bearings(yhat, Z, self.angular)
        Z = np.asarray(Z, dtype=float)
        return yhat, np.vstack([Z[0] * np.cos(Z[1]), Z[0] * np.sin(Z[1])])

    def inverse(self, x, z):
        """m = g(x, z) (2,), G_x (2, 3), G_z (2, 2): the landmark that produced observation z from pose x."""
        r, b = float(z[0]), float(z[1])
        a = b + float(x[2])
        c, s = math.cos(a), math.sin(a)
        m = np.array([x[0] + r * c, x[1] + r * s])
        gx = np.array([[1.0, 0.0, -r * s], [0.0, 1.0, r * c]])
        gz = np.array([[c, -r * s], [s, r * c]])
        return m, gx, gz

    def candidates(self, x, points, widen):
        """Boolean (k,): landmarks ``points`` (k, 2) predicted from pose x inside the footprint widened by
        ``widen`` = (range, bearing) — ``footprint_reference``'s answer from one compiled loop
        (``scan_kernels.in_footprint``)."""
        dr, db = widen
        return scan_kernels.in_footprint(_pose(x), _points(points, "points"), self.max_range,
                                         0.5 * self.field_of_view, float(dr), float(db))

    def footprint_reference(self, x, points, widen):
        """``candidates`` in numpy: the edge's prediction, then ``in_footprint``."""
        return self.in_footprint(self.predict(x, points, jacobians=False)[0], widen)

    def in_footprint(self, zhat, widen=None):
        """Boolean (k,): predicted observations inside the footprint widened by ``widen`` = (range, bearing)
        — by default the margins (a candidate); (0, 0) is the nominal footprint (a landmark that should be seen)."""
        zhat = np.asarray(zhat, dtype=float).reshape(-1, 2)
        dr, db = (self.range_margin, self.bearing_margin) if widen is None else widen
        ok = zhat[:, 0] <= self.max_range + dr
        if self.field_of_view < 2.0 * math.pi:
            ok &= np.abs(wrap_angle(zhat[:, 1])) <= 0.5 * self.field_of_view + db
        return ok


def _polar_jacobian(r, b):
    """∂[r cos b, r sin b]/∂[r, b] for arrays r, b: (k, 2, 2)."""
    c, s = np.cos(b), np.sin(b)
    G = np.empty((len(r), 2, 2))
    G[:, 0, 0], G[:, 0, 1], G[:, 1, 0], G[:, 1, 1] = c, -r * s, s, r * c
    return G


def _pose(x):
    """``x`` as a (3,) float array (the compiled paths read exactly three numbers), else ValueError."""
    x = np.ascontiguousarray(x, dtype=float)
    if x.shape != (3,):
        raise ValueError(f"x must be a pose (3,), got shape {x.shape}")
    return x


def _points(points, name):
    """``points`` as a contiguous (k, 2) float array, else ValueError naming ``name``."""
    points = np.ascontiguousarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"{name} must be a (k, 2) array of 2-D points, got shape {points.shape}")
    return points


def _non_negative(value, name):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) \
            or not np.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be a finite number ≥ 0, got {value!r}")
    return float(value)


def motion_jacobians(edge):
    """(F, Q) of a binary pose–pose edge at its vertices' current estimates (module docstring).

    The edge class's vectorised model is called directly on the two estimates (one edge): the same numbers as
    ``edge.jacobians()`` without its per-call checks (this runs once per tick); F and Q then come from one
    compiled call (``_propagation``)."""
    cls = type(edge)
    states = [edge.vertex(0).estimate[None, :], edge.vertex(1).estimate[None, :]]
    params = {name: np.asarray(edge.parameter(name), dtype=float)[None, ...] for name in cls.parameters}
    _, jac = cls.evaluate(states, edge.measurement[None, :], params, jacobians=True)
    F, Q, ok = _propagation(np.ascontiguousarray(jac[0][0]), np.ascontiguousarray(jac[1][0]),
                            np.ascontiguousarray(edge.information, dtype=float))
    if not ok:
        raise ValueError(f"edge: {type(edge).__name__} cannot propagate a pose (∂e/∂x_new is singular)")
    return F, Q


@njit(cache=True)
def _propagation(jk, jn, information):
    """F = −J_{k+1}⁻¹ J_k and Q = ½(M + Mᵀ), M = J_{k+1}⁻¹ Ω⁻¹ J_{k+1}⁻ᵀ; ok False when J_{k+1} is singular."""
    d = jn.shape[0]
    if abs(np.linalg.det(jn)) == 0.0 or not np.all(np.isfinite(jn)):
        return np.zeros((d, jk.shape[1])), np.zeros((d, d)), False
    jn_inv = np.linalg.inv(jn)
    F = -(jn_inv @ jk)
    Q = jn_inv @ np.linalg.inv(information) @ jn_inv.T
    return F, 0.5 * (Q + Q.T), True


def unwrap_bearings(predicted, observed, angular=(1,)):
    """Copies of ``predicted`` (k, d) and ``observed`` (d, m) whose angular components are mapped into one
    interval cut in the largest empty arc between all of them (module docstring)."""
    predicted = np.array(predicted, dtype=float).reshape(-1, np.shape(observed)[0])
    observed = np.array(observed, dtype=float)
    for i in angular:
        angles = np.concatenate([predicted[:, i], observed[i]])
        if angles.size == 0:
            continue
        a = np.sort(np.mod(angles, 2.0 * math.pi))
        gaps = np.diff(np.concatenate([a, [a[0] + 2.0 * math.pi]]))
        j = int(np.argmax(gaps))
        cut = a[j] + 0.5 * gaps[j]                     # middle of the largest empty arc
        predicted[:, i] = wrap_angle(predicted[:, i] - cut + math.pi)
        observed[i] = wrap_angle(observed[i] - cut + math.pi)
    return predicted, observed
