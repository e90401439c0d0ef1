"""One plotting style for every notebook, and one way to save report figures.

Usage in a notebook::

    from helpers import figures
    figures.use_style()
    fig, ax = plt.subplots()
    ...
    figures.save(fig, "05_snn_figure1")      # -> figures/05_snn_figure1.png and .pdf

Figures go to ``<repository>/figures/`` unless the environment variable ``WORKBOOK_FIGURES_DIR`` names another
directory (created on demand). Both files are rendered before either replaces an older copy, and PDFs carry no
creation date, so re-running gives identical files.
"""
from __future__ import annotations

import os
import pathlib
import re

import matplotlib as mpl
from matplotlib.figure import Figure

__all__ = ["STYLE", "use_style", "figures_dir", "save", "COLORS", "MAX_NAME_LENGTH"]

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

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")   # matched with fullmatch (``$`` would allow a final newline)
#: Longest figure name (characters).
MAX_NAME_LENGTH = 128


def use_style() -> None:
    """Apply the workbook's matplotlib style (call once at the top of a notebook)."""
    mpl.rcParams.update(STYLE)


def figures_dir() -> pathlib.Path:
    """Directory that receives report figures (created on demand; ValueError when it cannot be)."""
    env = os.environ.get("WORKBOOK_FIGURES_DIR")
    path = pathlib.Path(env) if env else pathlib.Path(__file__).resolve().parents[1] / "figures"
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        what = f"WORKBOOK_FIGURES_DIR={env!r}" if env else f"the figures directory {str(path)!r}"
        raise ValueError(f"{what} must name a directory that exists or can be created: "
                         f"{exc.strerror or exc}") from None
    return path


def save(fig: Figure, name: str) -> tuple[pathlib.Path, pathlib.Path]:
    """Write ``fig`` to ``figures/<name>.png`` and ``figures/<name>.pdf``; returns the two paths.

    ``name`` is a plain file stem (letters, digits, ``_ . -``, starting with a letter or digit, at most
    ``MAX_NAME_LENGTH`` characters; no directories, no extension). If rendering fails, the old files stay.
    """
    if not hasattr(fig, "savefig"):
        raise ValueError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
    if not isinstance(name, str) or not _NAME.fullmatch(name) or name.endswith((".png", ".pdf")) \
            or len(name) > MAX_NAME_LENGTH:
        shown = name if not isinstance(name, str) or len(name) <= 40 else name[:37] + "..."
        raise ValueError(f"name must be a plain file stem of at most {MAX_NAME_LENGTH} characters such as "
                         f"'05_snn_figure1', got {shown!r}")
    out = figures_dir()
    targets = (out / f"{name}.png", out / f"{name}.pdf")
    temps = [out / f".{name}.{os.getpid()}.tmp.{ext}" for ext in ("png", "pdf")]
    try:
        fig.savefig(temps[0], format="png")
        fig.savefig(temps[1], format="pdf", metadata={"CreationDate": None, "ModDate": None})
        for tmp, target in zip(temps, targets):
            os.replace(tmp, target)           # atomic: a reader sees the old file or the new one
    finally:
        for tmp in temps:
            tmp.unlink(missing_ok=True)
    return targets
