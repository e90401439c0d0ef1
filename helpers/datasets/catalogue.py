"""The datasets shipped in ``data/datasets`` (gzipped copies of GTSAM's example files), by name."""

from ..graph import VertexSE2
from ..paths import data_path
from .graph_data import build_optimizer, check_pose_class
from .toro_g2o import read_g2o, read_toro
from .victoria_park import read_victoria_park

__all__ = ["DATASETS", "dataset_path", "read_dataset", "load_dataset"]

#: name -> file in data/datasets; the name is the file's stem in GTSAM's ``gtsam/Data`` (origin: data/README.md)
DATASETS = {"w100": "w100.graph.gz", "w10000": "w10000.graph.gz", "victoria_park": "victoria_park.txt.gz",
            "example": "example.graph.gz", "w100_30": "w100_30.g2o.gz", "w20000": "w20000.txt.gz",
            "cityTrees_reduced_1k": "cityTrees_reduced_1k.g2o.gz",
            "victoriaPark_reduced_1k": "victoriaPark_reduced_1k.g2o.gz",
            "noisyToyGraph": "noisyToyGraph.txt.gz", "optimizedNoisyToyGraph": "optimizedNoisyToyGraph.txt.gz",
            "orientationsNoisyToyGraph": "orientationsNoisyToyGraph.txt.gz", "pose2example": "pose2example.txt.gz"}

#: the reader of each dataset (the format of its records, whatever the file's suffix)
_READERS = {"w100": read_toro, "w10000": read_toro, "example": read_toro, "w20000": read_toro,
            "victoria_park": read_victoria_park, "w100_30": read_g2o, "cityTrees_reduced_1k": read_g2o,
            "victoriaPark_reduced_1k": read_g2o, "noisyToyGraph": read_g2o, "optimizedNoisyToyGraph": read_g2o,
            "orientationsNoisyToyGraph": read_g2o, "pose2example": read_g2o}


def _known(name):
    if not isinstance(name, str):
        raise ValueError(f"name must be a dataset name (a str), got {name!r}; expected one of {sorted(DATASETS)}")
    if name not in DATASETS:
        raise ValueError(f"unknown dataset {name!r}; expected one of {sorted(DATASETS)}")
    return name


def dataset_path(name):
    """Full path of a dataset shipped with the workbook (``data/datasets/<file>.gz``)."""
    return data_path("datasets", DATASETS[_known(name)])


def read_dataset(name):
    """The GraphData of a shipped dataset, read with its format's reader."""
    return _READERS[_known(name)](dataset_path(name))


def load_dataset(name, pose_class=VertexSE2, optimizer_class=None):
    """A graph (``optimizer_class``, default the course's SparseOptimizer) for a shipped dataset
    (``sorted(DATASETS)``), first pose fixed (or the file's FIX vertices), structure built."""
    check_pose_class(pose_class)
    data = read_dataset(name)
    opt = build_optimizer(data, pose_class=pose_class, **({} if optimizer_class is None else
                                                          {"optimizer_class": optimizer_class}))
    opt.initialize_optimization()
    return opt
