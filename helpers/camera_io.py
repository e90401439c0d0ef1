"""Reading and writing a camera calibration as an OpenCV FileStorage file (``data/camera.xml``): a map ``camera``
with ``camera_matrix`` (3×3), ``distortion_coefficients`` (12×1), ``flags`` (int) and ``imageSize`` (width height).
"""
from __future__ import annotations

import numbers
import os
import tempfile
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from .validation import float_array

__all__ = ["read_camera_xml", "write_camera_xml", "check_calibration", "REQUIRED_FLAGS"]

CALIB_RATIONAL_MODEL = 16384
CALIB_THIN_PRISM_MODEL = 32768
CALIB_TILTED_MODEL = 262144
REQUIRED_FLAGS = CALIB_RATIONAL_MODEL | CALIB_THIN_PRISM_MODEL


def check_calibration(K: ArrayLike, dist_coeffs: ArrayLike, image_size: ArrayLike, flags: int) \
        -> tuple[np.ndarray, np.ndarray, tuple[int, int], int]:
    """The checked calibration values (K (3, 3) copy, 12 distortion coefficients (4, 5 or 8 zero-padded),
    (width, height) ints, flags int); anything else raises ValueError naming the argument."""
    K = np.array(float_array(K, "K"))
    if K.shape != (3, 3) or not np.all(np.isfinite(K)):
        raise ValueError(f"K must be a finite (3, 3) camera matrix, got shape {K.shape}")
    if K[0, 1] != 0 or K[1, 0] != 0 or K[2, 0] != 0 or K[2, 1] != 0 or K[2, 2] != 1:
        raise ValueError("K must have the form [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew)")
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise ValueError(f"K must have positive focal lengths, got fx={K[0, 0]}, fy={K[1, 1]}")
    d = float_array(dist_coeffs, "dist_coeffs").ravel()
    if d.size not in (4, 5, 8, 12):
        raise ValueError(f"dist_coeffs must have 12 entries (k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4), got {d.size}")
    if not np.all(np.isfinite(d)):
        raise ValueError("dist_coeffs must be finite (no NaN/inf)")
    d = np.concatenate([d, np.zeros(12 - d.size)])
    try:
        size = float_array(image_size, "image_size")
    except ValueError:
        size = np.zeros(0)      # reported below with the expected form
    if size.shape != (2,) or not np.all(np.isfinite(size)) or np.any(size != np.round(size)) or np.any(size <= 0):
        raise ValueError(f"image_size must be two positive integers (width, height), got {image_size!r}")
    if isinstance(flags, bool) or not isinstance(flags, numbers.Integral):
        raise ValueError(f"flags must be an integer, got {flags!r}")
    if (flags & REQUIRED_FLAGS) != REQUIRED_FLAGS or flags & CALIB_TILTED_MODEL:
        raise ValueError(f"flags must include CALIB_RATIONAL_MODEL and CALIB_THIN_PRISM_MODEL and not "
                         f"CALIB_TILTED_MODEL, got {flags}")
    return K, d, (int(size[0]), int(size[1])), int(flags)


def _path(path: str | Path) -> Path:
    if not isinstance(path, (str, Path)) or not str(path):
        raise ValueError(f"path must be a file name (str or pathlib.Path), got {path!r}")
    return Path(path)


def _read_node(fs: object, path: Path) -> tuple[np.ndarray, np.ndarray, tuple[int, int], int]:
    """(K, dist_coeffs, image_size, flags) from the map node ``camera`` of an open FileStorage."""
    node = fs.getNode("camera")
    if node.empty() or not node.isMap():
        raise ValueError(f"{path}: missing map node 'camera'")
    K, d = node.getNode("camera_matrix").mat(), node.getNode("distortion_coefficients").mat()
    fl, sz = node.getNode("flags"), node.getNode("imageSize")
    for name, bad in (("camera_matrix", K is None or K.shape != (3, 3)),
                      ("distortion_coefficients", d is None or d.size != 12),
                      ("flags", not fl.isInt()),
                      ("imageSize", not sz.isSeq() or sz.size() != 2 or not all(sz.at(k).isInt() for k in range(2)))):
        if bad:
            raise ValueError(f"{path}: node 'camera/{name}' is missing or malformed")
    return K.astype(float), d.astype(float), (int(sz.at(0).real()), int(sz.at(1).real())), int(fl.real())


def read_camera_xml(path: str | Path) -> tuple[np.ndarray, np.ndarray, tuple[int, int], int]:
    """(K (3×3), dist_coeffs (as stored), image_size (width, height), flags) read from ``path``; a missing or
    unreadable file, or a missing or malformed node, raises ValueError naming the path."""
    import cv2

    path = _path(path)
    if not path.is_file():
        raise ValueError(f"path: camera file {path} does not exist")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:  # OpenCV's parser raises cv2.error (wrapped in SystemError)
        raise ValueError(f"path: {path} is not a readable OpenCV FileStorage file ({type(exc).__name__})") from None
    try:
        if not fs.isOpened():
            raise ValueError(f"path: {path} is not a readable OpenCV FileStorage file")
        return _read_node(fs, path)
    finally:
        fs.release()


def write_camera_xml(path: str | Path, K: ArrayLike, dist_coeffs: ArrayLike, image_size: ArrayLike, flags: int) -> Path:
    """Write a calibration in the format :func:`read_camera_xml` reads (12 coefficients, zero-padded from 4, 5 or
    8). The values are checked first (``check_calibration``); the file is written next to ``path`` and renamed
    onto it, so a failed write leaves an existing file as it was. Returns the path."""
    import cv2

    path = _path(path)
    K, d, (width, height), flags = check_calibration(K, dist_coeffs, image_size, flags)
    if not path.parent.is_dir():
        raise ValueError(f"path: folder {path.parent} does not exist")
    fd, tmp = tempfile.mkstemp(suffix=".xml", dir=path.parent)
    os.close(fd)
    try:
        fs = cv2.FileStorage(tmp, cv2.FILE_STORAGE_WRITE)
        fs.startWriteStruct("camera", cv2.FileNode_MAP)
        fs.write("camera_matrix", K)
        fs.write("distortion_coefficients", d.reshape(12, 1))
        fs.write("flags", flags)
        fs.startWriteStruct("imageSize", cv2.FileNode_SEQ | cv2.FileNode_FLOW)
        fs.write("", width)
        fs.write("", height)
        fs.endWriteStruct()
        fs.endWriteStruct()
        fs.release()
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return path
