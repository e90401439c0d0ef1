"""Where the workbook's files live: the one helper every module uses to find ``data/`` (and the repository)."""
import pathlib

__all__ = ["repository_root", "data_dir", "data_path"]


def repository_root() -> pathlib.Path:
    """The workbook's top-level folder (``helpers`` is installed in editable mode from it)."""
    return pathlib.Path(__file__).resolve().parents[1]


def data_dir() -> pathlib.Path:
    """The workbook's ``data/`` folder."""
    return repository_root() / "data"


def data_path(*parts: str) -> pathlib.Path:
    """A path under ``data/``, e.g. ``data_path("datasets", "w10000.graph.gz")``.

    Every part is a non-empty relative path string without ``..`` (a path outside ``data/`` raises ValueError)."""
    for part in parts:
        if not isinstance(part, str) or not part or pathlib.PurePath(part).is_absolute() \
                or ".." in pathlib.PurePath(part).parts:
            raise ValueError(f"data_path parts must be non-empty relative names inside data/ (no '..'), got {part!r}")
    return data_dir().joinpath(*parts)
