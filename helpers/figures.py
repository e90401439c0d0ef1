"""One plotting style for every notebook, and one way to save report figures.

Usage in a notebook::

    from helpers import figures
    figures.use_style()
    fig, ax = plt.subplots()
    ...
    figures.save(fig, "05_snn_figure1")      # -> figures/05_snn_figure1.png and .pdf

Figures go to ``<repository>/figures/`` unless the environment variable ``WORKBOOK_FIGURES_DIR`` names
another directory (created on demand; a path that is or lies under a file raises ValueError naming the
variable). Names are plain file stems of at most ``MAX_NAME_LENGTH`` (128) characters.

The PNG/PDF pair is replaced together or not at all: both are rendered to temporary files in the target
directory, then both renamed into place; if anything fails (rendering either format, a rename) the
temporaries are removed and the previous pair, if any, is left as it was. So a reader never sees a
half-written figure, nor a new PNG beside an old PDF. The files get the usual mode (0o666 minus the umask,
as ``open()`` gives). PDF metadata carries no creation date, so re-running gives identical PDFs.
"""
from __future__ import annotations

import os
import pathlib
import re
import secrets
import shutil

import matplotlib as mpl

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
#: Longest figure name (characters); with its temporary-file decoration it stays well below 255 bytes.
MAX_NAME_LENGTH = 128


def use_style() -> None:
    """Apply the workbook's matplotlib style (call once at the top of a notebook)."""
    mpl.rcParams.update(STYLE)


def figures_dir() -> pathlib.Path:
    """Directory that receives report figures (created on demand)."""
    env = os.environ.get("WORKBOOK_FIGURES_DIR")
    path = pathlib.Path(env) if env else pathlib.Path(__file__).resolve().parents[1] / "figures"
    what = f"WORKBOOK_FIGURES_DIR={env!r}" if env else f"the figures directory {str(path)!r}"
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{what} must name a directory that exists or can be created: "
                         f"{exc.strerror or exc}") from None
    return path


def save(fig, name: str) -> tuple[pathlib.Path, pathlib.Path]:
    """Write ``fig`` to ``figures/<name>.png`` and ``figures/<name>.pdf``, both or neither (module docstring).

    Returns the two paths. ``name`` is a plain file stem (letters, digits, ``_ . -``, starting with a letter
    or digit, at most ``MAX_NAME_LENGTH`` characters; no directories, no extension).
    """
    if not hasattr(fig, "savefig"):
        raise ValueError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
    if not isinstance(name, str) or not _NAME.fullmatch(name) or name.endswith((".png", ".pdf")) \
            or len(name) > MAX_NAME_LENGTH:
        shown = name if not isinstance(name, str) or len(name) <= 40 else name[:37] + "..."
        raise ValueError(f"name must be a plain file stem of at most {MAX_NAME_LENGTH} characters such as "
                         f"'05_snn_figure1', got {shown!r}")
    out = figures_dir()
    targets = [out / f"{name}.png", out / f"{name}.pdf"]
    temps = []
    try:
        for ext, extra in (("png", {}), ("pdf", {"metadata": {"CreationDate": None, "ModDate": None}})):
            temps.append(_new_file(out, f".{name}.", f".{ext}"))
            fig.savefig(temps[-1], format=ext, **extra)
        _replace_together(temps, targets)
    finally:
        for tmp in temps:
            tmp.unlink(missing_ok=True)
    return targets[0], targets[1]


def _new_file(folder: pathlib.Path, prefix: str, suffix: str) -> pathlib.Path:
    """A new empty file with a random name, created with mode 0o666 & ~umask (``tempfile`` would give 0600)."""
    while True:
        path = folder / f"{prefix}{secrets.token_hex(4)}{suffix}"
        try:
            os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            continue
        return path


def _replace_together(sources, targets) -> None:
    """Rename every source onto its target; if a step fails, put back the targets already replaced."""
    backups, replaced = [], []   # backups: (target, second name of its previous content or None)
    try:
        for src, dst in zip(sources, targets):
            backups.append((dst, _backup(dst) if dst.exists() else None))
            os.replace(src, dst)   # atomic: a reader sees the old file or the new one, never none
            replaced.append(dst)
    except BaseException:
        for dst, backup in reversed(backups):
            if dst in replaced:
                if backup is not None:
                    os.replace(backup, dst)
                else:
                    dst.unlink(missing_ok=True)
        raise
    finally:
        for _, backup in backups:
            if backup is not None:
                backup.unlink(missing_ok=True)


def _backup(path: pathlib.Path) -> pathlib.Path:
    """A second name for ``path``'s current content (a hard link, or a copy where links are not supported)."""
    while True:
        backup = path.parent / f".{path.name}.{secrets.token_hex(4)}.old"
        try:
            os.link(path, backup)
        except FileExistsError:
            continue
        except OSError:
            shutil.copy2(path, backup)
        return backup
