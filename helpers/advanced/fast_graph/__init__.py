"""helpers.advanced.fast_graph — the graph optimiser for speed and for like-for-like comparisons with GTSAM.

``FastOptimizer`` holds the same vertices, edges and element storage as the course's ``helpers.graph.SparseOptimizer``
(``GraphElements``) with another engine underneath: the structure extended instead of rebuilt when elements are
only added, the Hessian pattern laid out from vertex blocks, the per-edge products compiled (``batched``), qdldl or
CHOLMOD (``cholmod_backend``, through cvxopt) chosen per pattern, and more algorithms: the coursework's "lm" and
"gn", GTSAM's LM schedule ("lm-gtsam"), and the "default" LM that converges from far away; ``VertexSE2Exp``
(GTSAM's Pose2 update). ``hessian_factors`` hands the online front-end the LDLᵀ factor of H.
"""
from .algorithms import GaussNewtonParams, GTSAMLevenbergMarquardtParams, LevenbergMarquardtParams
from .algorithms_default import DefaultParams
from .optimizer import FastOptimizer
from .vertex_exp import VertexSE2Exp

__all__ = ["FastOptimizer", "DefaultParams", "GaussNewtonParams", "LevenbergMarquardtParams",
           "GTSAMLevenbergMarquardtParams", "VertexSE2Exp"]
