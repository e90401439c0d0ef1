"""``VertexSE2Exp``: a planar pose with GTSAM's Pose2 update, for following GTSAM's iterations step for step.

Only ``FastOptimizer`` uses the ⊞ Jacobian ``oplus_jacobian_batch`` (it multiplies every edge Jacobian of such a
vertex by it); the course optimiser treats every ⊞ as additive to first order.
"""
import numpy as np

from ...graph.angles import wrap_angle
from ...graph.vertex import VertexSE2

__all__ = ["VertexSE2Exp"]


class VertexSE2Exp(VertexSE2):
    """Planar pose with the SE(2) exponential-map ⊞ of GTSAM's Pose2 (its default retraction):

        x ⊞ δ = x ∘ Exp(δ):  t' = t + R(ψ) V(δψ) δt,  ψ' = wrap(ψ + δψ),
        V(θ) = [[sin θ/θ, −(1 − cos θ)/θ], [(1 − cos θ)/θ, sin θ/θ]],   ∂(x ⊞ δ)/∂δ at 0 = blockdiag(R(ψ), 1).

    Same state and same edges as VertexSE2; only the update (and so the optimiser's path) differs: δ lives in the
    body frame, and large steps move along arcs. Use it to follow GTSAM's iterations step for step.
    """

    @staticmethod
    def oplus_batch(x, dx):
        th = dx[:, 2]
        small = np.abs(th) < 1e-8
        safe = np.where(small, 1.0, th)
        a = np.where(small, 1.0 - th * th / 6.0, np.sin(safe) / safe)
        b = np.where(small, th / 2.0, (1.0 - np.cos(safe)) / safe)
        ux = a * dx[:, 0] - b * dx[:, 1]
        uy = b * dx[:, 0] + a * dx[:, 1]
        c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
        out = np.empty_like(x)
        out[:, 0] = x[:, 0] + c * ux - s * uy
        out[:, 1] = x[:, 1] + s * ux + c * uy
        out[:, 2] = wrap_angle(x[:, 2] + th)
        return out

    @staticmethod
    def oplus_jacobian_batch(x):
        c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
        m = np.zeros((len(x), 3, 3))
        m[:, 0, 0], m[:, 0, 1], m[:, 1, 0], m[:, 1, 1], m[:, 2, 2] = c, -s, s, c, 1.0
        return m
