"""helpers.advanced.online_slam — online graph SLAM with data association (observations arrive without ids).

Modules by responsibility (each imports only modules listed before it, and the layers below the package):

    scan_kernels    compiled per-scan paths (footprint test, Cartesian density), each tested against its reference
    models          the measurement model (prediction and Jacobians from the edge class, inverse observation,
                    footprint, association space) and the motion propagation of any odometry edge
    covariance      joint marginal covariances of a few vertices from one LDLᵀ factorisation (columns of H⁻¹)
    window          the pose and the new landmarks since the last factorisation, as linear functions of it
    tracks          tentative / confirmed / dropped landmarks and the confirmation rule
    scan_guard      the front-end's arguments checked before anything changes, and a scan undone if it fails
    algorithms      "nn", "mahalanobis", "ml", "jcbb": the L09 algorithms behind one name each, and the check of
                    their options (``check_options``)
    decisions       individual compatibility, relative uncertainty, ambiguity of a pairing
    closure         loop closure: trusted candidates, duplicates, merging tentative landmarks into old ones
    verification    merges tested after the next optimisation (score test of the split) and undone if refused
    late            observations left out of the map (dropped tentative landmarks, discarded ones) pooled and paired
                    after a later optimisation, or made into a landmark when they agree among themselves
    frontend        ``OnlineFrontEnd``: candidates, joint predicted density, tracking, bookkeeping
    metrics         precision, recall, agreement after the best one-to-one matching; map error
    victoria_park   ``run_victoria_park``: the real dataset, associated online, and its report

``online_slam`` sits above ``graph``, ``association`` and ``datasets``; none of them imports it. DriveBot with the
ids hidden is ``helpers.advanced.hidden_ids`` (``run_hidden_ids(name, data_association="jcbb", …)``), which uses
this package.
"""
from .algorithms import ALGORITHMS, check_algorithm, check_options
from .frontend import OnlineFrontEnd, ScanResult
from .metrics import association_scores, best_matching, map_errors
from .models import RangeBearingModel
from .tracks import ConfirmationRules
from .victoria_park import VictoriaParkResults, run_victoria_park

__all__ = ["ALGORITHMS", "ConfirmationRules", "OnlineFrontEnd", "RangeBearingModel", "ScanResult",
           "VictoriaParkResults", "association_scores", "best_matching", "check_algorithm", "check_options",
           "map_errors", "run_victoria_park"]
