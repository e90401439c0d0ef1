"""One plotting style for every notebook, and one way to save report figures.

Usage in a notebook::

    from helpers import figures
    figures.use_style()
    fig, ax = plt.subplots()
    ...
    figures.save(fig, "05_snn_figure1")      # -> figures/05_snn_figure1.png and .pdf

Figures go to ``<repository>/figures/`` unless the environment variable ``WORKBOOK_FIGURES_DIR`` names
another directory. Both files are written to a temporary name first and then renamed, so a reader never
sees a half-written figure. PDF metadata carries no creation date, so re-running gives identical PDFs.
"""
from __future__ import annotations

import os
import pathlib
import re
import tempfile

import matplotlib as mpl

__all__ = ["STYLE", "use_style", "figures_dir", "save", "COLORS"]

#: Colours used consistently across notebooks (truth, estimate, covariance bounds, …).
COLORS = {
    "truth": "#222222",
    "estimate": "#1f77b4",
    "bound": "#d62728",
    "alt": "#2ca02c",
    "muted": "#7f7f7f",
}

STYLE = {
    "figure.figsize": (7.0, 4.2),
    "figure.dpi": 100,
    "savefig.dpi": 150,
    "savefig.bbox": "tight",
    "font.size": 10,
    "axes.titlesize": 11,
    "axes.labelsize": 10,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "legend.fontsize": 9,
    "legend.frameon": False,
    "lines.linewidth": 1.4,
    "image.cmap": "viridis",
    "pdf.fonttype": 42,
}

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


def use_style() -> None:
    """Apply the workbook's matplotlib style (call once at the top of a notebook)."""
    mpl.rcParams.update(STYLE)


def figures_dir() -> pathlib.Path:
    """Directory that receives report figures (created on demand)."""
    env = os.environ.get("WORKBOOK_FIGURES_DIR")
    path = pathlib.Path(env) if env else pathlib.Path(__file__).resolve().parents[1] / "figures"
    path.mkdir(parents=True, exist_ok=True)
    return path


def save(fig, name: str) -> tuple[pathlib.Path, pathlib.Path]:
    """Write ``fig`` to ``figures/<name>.png`` and ``figures/<name>.pdf`` atomically.

    Returns the two paths. ``name`` is a plain file stem (letters, digits, ``_ . -``; no directories,
    no extension).
    """
    if not hasattr(fig, "savefig"):
        raise ValueError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
    if not isinstance(name, str) or not _NAME.match(name) or name.endswith((".png", ".pdf")):
        raise ValueError(f"name must be a plain file stem such as '05_snn_figure1', got {name!r}")
    out = figures_dir()
    paths = []
    for ext, extra in (("png", {}), ("pdf", {"metadata": {"CreationDate": None, "ModDate": None}})):
        target = out / f"{name}.{ext}"
        fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=f".{ext}", dir=out)
        os.close(fd)
        try:
            fig.savefig(tmp, format=ext, **extra)
            os.replace(tmp, target)
        except BaseException:
            pathlib.Path(tmp).unlink(missing_ok=True)
            raise
        paths.append(target)
    return paths[0], paths[1]
