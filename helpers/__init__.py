"""Algorithms behind the SLAM course workbook.

One module per course concept, so a student can guess where a thing lives (layers and a concept map:
``helpers/README.md``):

- ``helpers.rotation``          rotation matrices and roll-pitch-yaw angles
- ``helpers.gaussian``          the square-root Gaussian (P = SᵀS, S upper-triangular)
- ``helpers.camera``            the calibrated camera model (12-coefficient OpenCV distortion)
- ``helpers.camera_io``         reading / writing the camera calibration file
- ``helpers.state_slam``        the SLAM state and the predicted feature bundle
- ``helpers.features``          Shi–Tomasi / Harris corner detection
- ``helpers.scene``             the rendered Lab 8 chessboard scene and pose recovery
- ``helpers.association``       compatibility tests and data-association algorithms
- ``helpers.graph``             the g2o-style sparse graph optimiser
- ``helpers.datasets``          TORO / g2o / Victoria Park readers; the datasets shipped in ``data/datasets``
- ``helpers.recorded_peers``    GTSAM / g2o results recorded by ``benchmarks/record_peers.py``
- ``helpers.drivebot``          the DriveBot simulator and SLAM system of the coursework
- ``helpers.figures``           the one plotting style and ``save(fig, name)``
- ``helpers.paths``             where ``data/`` is
- ``helpers.validation``        the shared argument checks (ValueError naming the argument)
- ``helpers.timing``            ``timed`` / ``best_of`` wall-clock timing
"""

__all__ = []
