"""Readers for the standard 2-D pose-graph datasets, and the copies shipped in ``data/datasets`` by name.

``read_dataset(name)`` / ``load_dataset(name)`` for ``name`` in ``sorted(DATASETS)`` (GTSAM's 2-D example files:
W100, W10000, Victoria Park, …; origin and licence in ``data/README.md``). Readers take plain or gzip files.

Formats (anything else raises DatasetFormatError, a ValueError naming the file and the 1-based line):

TORO ``.graph``   VERTEX2 id x y θ;  EDGE2 i j dx dy dθ I11 I12 I22 I33 I13 I23;  EQUIV i j (ignored);
                  BR pose landmark bearing range σ_bearing σ_range
2D g2o            VERTEX_SE2 id x y θ;  VERTEX_XY id x y;  FIX id;  EDGE_SE2 i j dx dy dθ I11 I12 I13 I22 I23 I33;
                  EDGE_SE2_XY i j dx dy I11 I12 I22;  LANDMARK2 (as EDGE_SE2_XY, own id space);  VERTEX2, EDGE2
victoria_park     ODOMETRY i j dx dy dθ c_xx c_xy c_xθ c_yy c_yθ c_θθ  (covariance);
                  LANDMARK i l x y c_xx c_xy c_yy                      (Cartesian, in the frame of pose i)

Conventions follow GTSAM (``readG2o`` / ``load2D``), so χ² values compare one to one (χ² = 2 × GTSAM's error):
relative poses become ``EdgeSE2``; EDGE2 information is in TORO order unless every matrix of the file is diagonal
in g2o order; a LANDMARK becomes a range-bearing edge with σ_range = √c_xx, σ_bearing = √(c_xx / 10) (an isotropic
covariance is required); LANDMARK2 / EDGE_SE2_XY become ``EdgeSE2PointXY``. Poses without a VERTEX line are
composed from the relative-pose edges, a landmark starts at its first observation, and the lowest-id pose is fixed
(or the FIX vertices). Duplicate vertex ids, self-loops, unreachable poses, unknown tags and a plain file whose last
line has no newline (a truncated copy) are errors; duplicate edges are independent measurements.
"""
from __future__ import annotations

import pathlib

from ..graph import SparseOptimizer, VertexSE2
from ..paths import data_path
from .graph_data import GraphData, build_optimizer, pose_arrays
from .readers import read_g2o, read_toro, read_victoria_park
from .records import DatasetFormatError

__all__ = ["GraphData", "DatasetFormatError", "read_toro", "read_g2o", "read_victoria_park", "dataset_path",
           "read_dataset", "load_dataset", "build_optimizer", "pose_arrays", "DATASETS"]

#: name -> (file in data/datasets, reader of its format); the name is the file's stem in GTSAM's ``gtsam/Data``
_FILES = {"w100": ("w100.graph.gz", read_toro), "w10000": ("w10000.graph.gz", read_toro),
          "example": ("example.graph.gz", read_toro), "w20000": ("w20000.txt.gz", read_toro),
          "victoria_park": ("victoria_park.txt.gz", read_victoria_park), "w100_30": ("w100_30.g2o.gz", read_g2o),
          "cityTrees_reduced_1k": ("cityTrees_reduced_1k.g2o.gz", read_g2o),
          "victoriaPark_reduced_1k": ("victoriaPark_reduced_1k.g2o.gz", read_g2o),
          "noisyToyGraph": ("noisyToyGraph.txt.gz", read_g2o),
          "optimizedNoisyToyGraph": ("optimizedNoisyToyGraph.txt.gz", read_g2o),
          "orientationsNoisyToyGraph": ("orientationsNoisyToyGraph.txt.gz", read_g2o),
          "pose2example": ("pose2example.txt.gz", read_g2o)}
#: name -> file in data/datasets (origin and licence: data/README.md)
DATASETS = {name: file for name, (file, _) in _FILES.items()}


def _known(name: str) -> str:
    if not isinstance(name, str):
        raise ValueError(f"name must be a dataset name (a str), got {name!r}; expected one of {sorted(DATASETS)}")
    if name not in DATASETS:
        raise ValueError(f"unknown dataset {name!r}; expected one of {sorted(DATASETS)}")
    return name


def dataset_path(name: str) -> pathlib.Path:
    """Full path of a dataset shipped with the workbook (``data/datasets/<file>.gz``)."""
    return data_path("datasets", DATASETS[_known(name)])


def read_dataset(name: str) -> GraphData:
    """The GraphData of a shipped dataset, read with its format's reader."""
    return _FILES[_known(name)][1](dataset_path(name))


def load_dataset(name: str, pose_class: type = VertexSE2, optimizer_class: type | None = None) -> SparseOptimizer:
    """A graph (``optimizer_class``, default the course's SparseOptimizer) for a shipped dataset
    (``sorted(DATASETS)``), first pose fixed (or the file's FIX vertices), structure built."""
    opt = build_optimizer(read_dataset(name), pose_class=pose_class, optimizer_class=optimizer_class or SparseOptimizer)
    opt.initialize_optimization()
    return opt
