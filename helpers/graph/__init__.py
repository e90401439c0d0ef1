"""helpers.graph — the coursework's g2o-style graph optimiser: vertices, edges, sparse Gauss–Newton / LM.

    g = SparseOptimizer()
    a, b = VertexSE2(0, [0, 0, 0], fixed=True), VertexSE2(1, [0.9, 0.1, 0.0])
    g.add_vertex(a); g.add_vertex(b)
    g.add_edge(EdgeSE2([a, b], measurement=[1, 0, 0], information=np.eye(3)))
    g.initialize_optimization()             # builds the structure (again after any add/remove/set_fixed)
    chi2 = g.optimize(50, algorithm="lm")   # "lm" or "gn"; g.statistics per iteration
    cov = g.compute_marginals([b])[b]       # 3×3 block of H⁻¹ at the solution

Every edge predicts h(x) from its vertices, with error e = h(x) − z (angles wrapped) and information Ω; the
optimiser minimises χ² = Σ eᵀΩe (``optimizer``). A new vertex class subclasses ``BaseVertex`` (``vertex``), a new
edge class ``BaseEdge`` (``edge``: a staticmethod ``evaluate`` returns e and the Jacobians for all edges of the
class at once); the standard 2D set is in ``edges2d``.
"""

from .angles import wrap_angle, wrap_angle_mod
from .edge import BaseEdge, batch_matrix, check_information, information_from_covariance
from .edges2d import (EdgeHeadingPrior, EdgePointPrior, EdgePositionPrior, EdgeRangeBearing, EdgeSE2, EdgeSE2PointXY,
                      EdgeSE2Prior)
from .errors import GaugeFreedomError, GraphError, NonFiniteError
from .optimizer import SparseOptimizer
from .vertex import BaseVertex, VertexPointXY, VertexSE2

__all__ = ["wrap_angle", "wrap_angle_mod", "BaseVertex", "VertexSE2", "VertexPointXY", "BaseEdge", "check_information",
           "information_from_covariance", "batch_matrix", "EdgeSE2", "EdgeSE2Prior", "EdgePositionPrior",
           "EdgeHeadingPrior", "EdgeRangeBearing", "EdgePointPrior", "EdgeSE2PointXY", "SparseOptimizer", "GraphError",
           "GaugeFreedomError", "NonFiniteError"]
