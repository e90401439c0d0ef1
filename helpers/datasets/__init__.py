"""Readers for the standard 2D pose-graph / SLAM datasets, and ``load_dataset`` for the copies in ``data/datasets``.

The datasets the workbook ships (every 2-D graph file of GTSAM's ``gtsam/Data`` that GTSAM reads, e.g. W100,
W10000, Victoria Park, example.graph; list, origin and licence in ``data/README.md``) are gzipped in
``data/datasets/`` and load by name: ``load_dataset(name)`` for ``name`` in ``sorted(DATASETS)``. Every reader
also takes plain or gzip files (gzip is recognised by its magic bytes).

Formats (strict: anything else raises DatasetFormatError, a ValueError naming the file and the 1-based line):

TORO ``.graph``   VERTEX2 id x y θ
                  EDGE2 i j dx dy dθ I11 I12 I22 I33 I13 I23      (information, TORO order; see layout below)
                  EQUIV i j                                        (ignored, as GTSAM does)
                  BR pose landmark bearing range σ_bearing σ_range (GTSAM's example.graph)
2D g2o            VERTEX_SE2 id x y θ;  VERTEX_XY id x y;  FIX id
                  EDGE_SE2 i j dx dy dθ I11 I12 I13 I22 I23 I33    (information, upper triangle row-major)
                  EDGE_SE2_XY i j dx dy I11 I12 I22                (point in the frame of pose i)
                  LANDMARK2 pose landmark dx dy I11 I12 I22        (as EDGE_SE2_XY; GTSAM's cityTrees /
                                                                    victoriaPark_reduced_1k files)
                  VERTEX2, EDGE2                                   (TORO's records, as in GTSAM's w100_30.g2o)
victoria_park     ODOMETRY i j dx dy dθ c_xx c_xy c_xθ c_yy c_yθ c_θθ   (covariance)
                  LANDMARK i l x y c_xx c_xy c_yy                  (Cartesian, in the frame of pose i)

Conventions follow GTSAM (``gtsam.readG2o`` / ``gtsam.load2D``) so that χ² values compare one to one
(χ² = 2 × GTSAM's error):
- relative pose measurements become ``EdgeSE2`` (GTSAM's BetweenFactor error);
- EDGE2 information layout: TORO order, unless the file's EDGE2 matrices are all diagonal in g2o order
  (I11 0 0 I22 0 I33: the pattern GTSAM's NoiseFormatAUTO recognises; w100_30.g2o, w20000.txt), then g2o order.
  The six numbers are information (as readG2o and both formats say); a file mixing the two patterns is an error;
- a LANDMARK (x, y) becomes a range-bearing edge with z = (hypot(x, y), atan2(y, x)), σ_range = √c_xx and
  σ_bearing = √(c_xx / 10) (load2D's rule, which needs an isotropic covariance: c_xy = 0 and |c_xx − c_yy| < 1e-4,
  else an error, where load2D would silently use σ = 1); a BR line gives z = (range, bearing) with its own sigmas;
- LANDMARK2 / EDGE_SE2_XY become ``EdgeSE2PointXY``. GTSAM's readG2o ignores LANDMARK2 lines (its graph of the
  cityTrees / victoriaPark_reduced files has the poses only);
- initial poses are the VERTEX lines; poses without one are composed from the relative-pose edges in file order
  (the first pose at the origin), with further passes for edges met before either end had a value; a landmark
  starts at its first observation, pose ⊞ (measurement);
- the lowest-id pose is fixed (GTSAM puts a prior on it instead), or the FIX vertices of a g2o file.

Decisions on records that are legal but suspicious (each tested):
- duplicate vertex ids (VERTEX2, VERTEX_SE2, VERTEX_XY; g2o vertices share one id space): error (GTSAM too);
- duplicate edges (same ends, even the same numbers): allowed — independent measurements, as in g2o and GTSAM;
- an edge from a vertex to itself: error; a relative-pose edge touching a g2o point, a point edge ending at a pose:
  error; FIX of an id that no vertex or edge of the file has: error (FIX twice: allowed, idempotent);
- LANDMARK2 landmarks have their own id space (GTSAM's L(j)), so a file may not mix them with g2o points;
- a pose that no VERTEX line or chain of relative-pose edges reaches: error (GTSAM would put it at the origin);
- a BR range ≤ 0 or a LANDMARK at (0, 0): error (bearing undefined); EQUIV: ignored; any other tag: error
  (GTSAM and g2o skip unknown tags, which would give a partial graph silently); ``#`` lines: comments;
- a plain file whose last line has no newline: error (a truncated copy; gzip files are checked by their CRC).
"""

from .catalogue import DATASETS, dataset_path, load_dataset, read_dataset
from .graph_data import GraphData, build_optimizer, pose_arrays
from .records import DatasetFormatError
from .toro_g2o import read_g2o, read_toro
from .victoria_park import read_victoria_park

__all__ = ["GraphData", "DatasetFormatError", "read_toro", "read_g2o", "read_victoria_park", "dataset_path",
           "read_dataset", "load_dataset", "build_optimizer", "pose_arrays", "DATASETS"]
