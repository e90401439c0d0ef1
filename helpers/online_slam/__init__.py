"""helpers.online_slam — online graph SLAM with data association (observations arrive without ids).

Modules by responsibility (each imports only modules listed before it, and the layers below the package):

    models          the measurement model (prediction and Jacobians from the edge class, inverse observation,
                    footprint, association space) and the motion propagation of any odometry edge
    covariance      joint marginal covariances of a few vertices from one LDLᵀ factorisation (columns of H⁻¹)
    window          the pose and the new landmarks since the last factorisation, as linear functions of it
    tracks          tentative / confirmed / dropped landmarks and the confirmation rule
    algorithms      "nn", "mahalanobis", "ml", "jcbb": the L09 algorithms behind one name each
    decisions       individual compatibility, relative uncertainty, ambiguity of a pairing
    closure         loop closure: trusted candidates, duplicates, merging tentative landmarks into old ones
    frontend        ``OnlineFrontEnd``: candidates, joint predicted density, tracking, bookkeeping
    metrics         precision, recall, agreement after the best one-to-one matching; map error
    drivebot_system ``AssociatingSLAMSystem`` (DriveBot with the ids hidden), ``SensorCorruption`` (clutter, misses)
    drivebot        ``run_question_with_association`` and ``AssociationResults.association_report()``
    victoria_park   ``run_victoria_park``: the real dataset, associated online, and its report

``online_slam`` sits above ``graph``, ``association``, ``datasets`` and ``drivebot``; none of them imports it.
"""
from .algorithms import ALGORITHMS
from .drivebot import AssociationResults, run_question_with_association
from .frontend import OnlineFrontEnd, ScanResult
from .metrics import association_scores, best_matching
from .models import RangeBearingModel
from .tracks import ConfirmationRules
from .victoria_park import VictoriaParkResults, run_victoria_park

__all__ = ["ALGORITHMS", "AssociationResults", "ConfirmationRules", "OnlineFrontEnd", "RangeBearingModel",
           "ScanResult", "VictoriaParkResults", "association_scores", "best_matching", "run_question_with_association",
           "run_victoria_park"]
