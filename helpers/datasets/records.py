"""Reading a dataset file into records, the named error, and the checks every format shares.

``scan`` turns a file (plain or gzip) into {tag: (line numbers, (N, k) float array)}. What it cannot read raises
:class:`DatasetFormatError` naming the file and, for a line, its 1-based number: a missing file, corrupt gzip data,
bytes that are not UTF-8 text, NUL bytes, an empty file, a plain file whose last line has no newline (a truncated
copy; gzip data has its own CRC), an unknown tag, a wrong number of fields, a field that is not a plain decimal
number, NaN or ±inf.
"""
from __future__ import annotations

import gzip
import os
import pathlib
import zlib
from typing import NoReturn

import numpy as np

__all__ = ["DatasetFormatError", "fail", "scan", "ids", "check_spd", "check_unique", "check_distinct_ends",
           "first_bad", "sym3", "MAX_ID"]

#: ids are parsed as floats: they must be exact there
MAX_ID = 2 ** 53

#: 3-D records of the g2o / TORO families (named in the error: only 2-D files are read)
_THREE_D = ("VERTEX3", "EDGE3", "VERTEX_SE3:QUAT", "EDGE_SE3:QUAT", "VERTEX_TRACKXYZ", "EDGE_SE3_TRACKXYZ",
            "PARAMS_SE3OFFSET", "EDGE_SE3_XYZ")


class DatasetFormatError(ValueError):
    """A dataset file that is not what its format says.

    ``path`` names the file, ``line`` the 1-based line (None when the problem is the whole file: missing,
    empty, not text, corrupt gzip data) and ``reason`` what is wrong; the message is ``path:line: reason``.
    """

    def __init__(self, path: str | os.PathLike, line: int | None, reason: str) -> None:
        self.path, self.line, self.reason = str(path), line, reason
        where = self.path if line is None else f"{self.path}:{line}"
        super().__init__(f"{where}: {reason}")

    def __reduce__(self):
        return type(self), (self.path, self.line, self.reason)


def fail(path: str | os.PathLike, lineno: int | None, message: str) -> NoReturn:
    raise DatasetFormatError(path, lineno, message)


def _file_bytes(path: str | os.PathLike) -> tuple[bytes, bool]:
    """(raw bytes, was gzip) of an existing regular file; gzip is recognised by its magic bytes."""
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path must be a file path (str or os.PathLike), got {path!r}")
    path = pathlib.Path(path)
    if not path.exists():
        fail(path, None, "dataset file not found")
    if not path.is_file():
        fail(path, None, "is not a regular file (a directory?)")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        fail(path, None, f"cannot be read: {exc.strerror or exc}")
    if raw[:2] == b"\x1f\x8b":
        try:
            return gzip.decompress(raw), True
        except (OSError, EOFError, zlib.error) as exc:
            fail(path, None, f"corrupt or truncated gzip data ({exc})")
    if path.suffix == ".gz":
        fail(path, None, "has a .gz suffix but is not gzip data")
    return raw, False


def _lines(path: str | os.PathLike) -> list[str]:
    """The file's lines (split at \\n, \\r\\n or \\r, as Python's text files do), after the whole-file checks."""
    raw, packed = _file_bytes(path)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        head = raw[:exc.start].replace(b"\r\n", b"\n").replace(b"\r", b"\n")
        fail(path, head.count(b"\n") + 1, f"not UTF-8 text (byte 0x{raw[exc.start]:02x}): is it a binary file?")
    if "\x00" in text:
        head = text[:text.index("\x00")].replace("\r\n", "\n").replace("\r", "\n")
        fail(path, head.count("\n") + 1, "contains NUL bytes: is it a binary (or UTF-16) file?")
    if text.startswith("\ufeff"):  # a UTF-8 byte-order mark
        text = text[1:]
    if not text.strip():
        fail(path, None, "is empty")
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    if not packed and lines[-1].strip():
        fail(path, len(lines), "the last line does not end with a newline: the file looks truncated "
                               "(if it is complete, end it with a newline)")
    return lines


def _to_array(path: str | os.PathLike, tag: str, lines: list[int], rows: list[list[str]], k: int) -> np.ndarray:
    """(N, k) floats; on failure the first offending line is reported."""
    try:
        return np.array(rows, dtype=float).reshape(len(rows), k)
    except ValueError:
        for ln, r in zip(lines, rows):
            try:
                [float(f) for f in r]
            except ValueError:
                fail(path, ln, f"{tag}: not a number in {' '.join(r)!r}")
        raise


def scan(path: str | os.PathLike, counts: dict[str, int]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Split a file into records: {tag: (line numbers, (N, counts[tag]) float array)}; strict checks.

    Lines that are blank or start with ``#`` are comments. Field counts are checked per line; numbers are
    converted in bulk (and only on failure line by line, to report the offending line). A record must be
    ASCII and its numbers plain decimals (no ``_`` digit separators, which Python's float would accept).
    """
    recs = {tag: ([], []) for tag in counts}
    for lineno, line in enumerate(_lines(path), start=1):
        fields = line.split()
        if not fields or fields[0].startswith("#"):
            continue
        tag = fields[0]
        if tag not in counts:
            hint = " (a 3-D record: only 2-D files are read)" if tag in _THREE_D else ""
            fail(path, lineno, f"unknown record {tag!r}{hint} (expected one of {', '.join(counts)})")
        if len(fields) - 1 != counts[tag]:
            fail(path, lineno, f"{tag} needs {counts[tag]} numbers, got {len(fields) - 1}")
        if not line.isascii() or line.count("_") != tag.count("_"):
            fail(path, lineno, f"{tag}: not a number in {' '.join(fields[1:])!r}")
        recs[tag][0].append(lineno)
        recs[tag][1].append(fields[1:])
    out = {}
    for tag, (lines, rows) in recs.items():
        arr = _to_array(path, tag, lines, rows, counts[tag])
        bad = ~np.isfinite(arr).all(axis=1)
        if bad.any():
            fail(path, lines[int(np.argmax(bad))], f"{tag}: non-finite value")
        out[tag] = (np.array(lines, dtype=int), arr)
    return out


def first_bad(mask: np.ndarray) -> int:
    """Index of the first row of ``mask`` (1-D, or 2-D: any column) that is true."""
    return int(np.argmax(mask.any(axis=1) if mask.ndim > 1 else mask))


def ids(path: str | os.PathLike, tag: str, lines: np.ndarray, values: np.ndarray, what: str = "ids") -> np.ndarray:
    """Integer ids (non-negative, exact in a float: below 2**53) as int64."""
    bad = ~((values == np.round(values)) & (values >= 0) & (values < MAX_ID))
    if bad.any():
        fail(path, lines[first_bad(bad)], f"{tag}: {what} must be non-negative integers (below 2**53)")
    return values.astype(np.int64)


def check_spd(path: str | os.PathLike, tag: str, lines: np.ndarray, mats: np.ndarray,
              what: str = "information") -> None:
    """Every matrix of ``mats`` (N, k, k) positive definite."""
    bad = ~(np.linalg.eigvalsh(mats).min(axis=1) > 0) if len(mats) else np.zeros(0, bool)
    if bad.any():
        fail(path, lines[int(np.argmax(bad))], f"{tag}: {what} matrix is not positive definite")


def check_unique(path: str | os.PathLike, what: str, id_values: np.ndarray, lines: np.ndarray) -> None:
    """No id twice (``lines`` may come from several tags); the error names both lines."""
    id_values, lines = np.asarray(id_values), np.asarray(lines)
    if len(np.unique(id_values)) == len(id_values):
        return
    seen = {}
    for line, key in sorted(zip(lines.tolist(), id_values.tolist())):
        if key in seen:
            fail(path, line, f"{what} {key} is defined twice (first on line {seen[key]})")
        seen[key] = line


def check_distinct_ends(path: str | os.PathLike, tag: str, lines: np.ndarray, ij: np.ndarray) -> None:
    """No edge from a vertex to itself."""
    same = ij[:, 0] == ij[:, 1]
    if same.any():
        t = int(np.argmax(same))
        fail(path, lines[t], f"{tag}: an edge must join two different vertices, got {ij[t, 0]} → {ij[t, 1]}")


def sym3(a11: np.ndarray, a12: np.ndarray, a13: np.ndarray, a22: np.ndarray, a23: np.ndarray,
         a33: np.ndarray) -> np.ndarray:
    """(N, 3, 3) symmetric matrices from their upper triangles."""
    return np.stack([np.stack([a11, a12, a13], -1), np.stack([a12, a22, a23], -1),
                     np.stack([a13, a23, a33], -1)], -2)
