"""Reading and writing a camera calibration as an OpenCV FileStorage file (``data/camera.xml``).

The file holds a map ``camera`` with ``camera_matrix`` (3×3), ``distortion_coefficients`` (12×1), ``flags``
(int) and ``imageSize`` (two ints: width height). This module only moves those four values between the file
and numpy; ``helpers.camera.Camera.from_xml`` / ``to_xml`` check them and build the model.
"""
from __future__ import annotations

from pathlib import Path

import numbers

import numpy as np

from .validation import float_array

__all__ = ["read_camera_xml", "write_camera_xml", "check_calibration", "CALIB_RATIONAL_MODEL",
           "CALIB_THIN_PRISM_MODEL", "CALIB_TILTED_MODEL"]

CALIB_RATIONAL_MODEL = 16384
CALIB_THIN_PRISM_MODEL = 32768
CALIB_TILTED_MODEL = 262144
_REQUIRED_FLAGS = CALIB_RATIONAL_MODEL | CALIB_THIN_PRISM_MODEL


def check_calibration(K, dist_coeffs, image_size, flags):
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
    if (flags & _REQUIRED_FLAGS) != _REQUIRED_FLAGS or flags & CALIB_TILTED_MODEL:
        raise ValueError(f"flags must include CALIB_RATIONAL_MODEL and CALIB_THIN_PRISM_MODEL and not "
                         f"CALIB_TILTED_MODEL, got {flags}")
    return K, d, (int(size[0]), int(size[1])), int(flags)


def _path(path):
    if not isinstance(path, (str, Path)) or not str(path):
        raise ValueError(f"path must be a file name (str or pathlib.Path), got {path!r}")
    return Path(path)


def _matrix(node, path, name, shapes):
    m = node.getNode(name).mat()
    if m is None or np.asarray(m).shape not in shapes:
        raise ValueError(f"{path}: node 'camera/{name}' must be an opencv-matrix of shape {shapes[0]}")
    return np.asarray(m, dtype=float)


def _read_node(node, path):
    """(K, dist_coeffs, image_size, flags) from the ``camera`` map node of an open FileStorage."""
    if node.empty() or not node.isMap():
        raise ValueError(f"{path}: missing map node 'camera'")
    K = _matrix(node, path, "camera_matrix", [(3, 3)])
    d = _matrix(node, path, "distortion_coefficients", [(12, 1), (1, 12), (12,)])
    fl = node.getNode("flags")
    if fl.empty() or not fl.isInt():
        raise ValueError(f"{path}: node 'camera/flags' must be an integer")
    flags = int(fl.real())
    sz = node.getNode("imageSize")
    if sz.empty() or not sz.isSeq() or sz.size() != 2 or not all(sz.at(k).isInt() for k in range(2)):
        raise ValueError(f"{path}: node 'camera/imageSize' must be a sequence of 2 integers (width height)")
    return K, d, (int(sz.at(0).real()), int(sz.at(1).real())), flags


def read_camera_xml(path):
    """(K (3×3), dist_coeffs (as stored), image_size (width, height), flags) read from ``path``.

    A missing or unreadable file, or a missing or malformed node, raises ValueError naming the path."""
    import cv2

    path = _path(path)
    if not path.is_file():
        raise ValueError(f"path: camera file {path} does not exist")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:  # OpenCV's parser raises cv2.error (wrapped in SystemError)
        raise ValueError(f"path: {path} is not a readable OpenCV FileStorage file "
                         f"({type(exc).__name__})") from None
    try:
        if not fs.isOpened():
            raise ValueError(f"path: {path} is not a readable OpenCV FileStorage file")
        return _read_node(fs.getNode("camera"), path)
    finally:
        fs.release()


def write_camera_xml(path, K, dist_coeffs, image_size, flags) -> None:
    """Write a calibration in the format :func:`read_camera_xml` reads (12 distortion coefficients); the values
    are checked first (:func:`check_calibration`), so a bad value never leaves a half-written file."""
    import cv2

    path = _path(path)
    K, dist_coeffs, image_size, flags = check_calibration(K, dist_coeffs, image_size, flags)
    if not path.parent.is_dir():
        raise ValueError(f"path: the folder of {path} does not exist")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    except (cv2.error, SystemError) as exc:
        raise ValueError(f"path: cannot open {path} for writing ({type(exc).__name__})") from None
    if not fs.isOpened():
        raise ValueError(f"path: cannot open {path} for writing")
    fs.startWriteStruct("camera", cv2.FileNode_MAP)
    fs.write("camera_matrix", np.asarray(K, dtype=float))
    fs.write("distortion_coefficients", np.asarray(dist_coeffs, dtype=float).reshape(12, 1))
    fs.write("flags", int(flags))
    fs.startWriteStruct("imageSize", cv2.FileNode_SEQ | cv2.FileNode_FLOW)
    fs.write("", int(image_size[0]))
    fs.write("", int(image_size[1]))
    fs.endWriteStruct()
    fs.endWriteStruct()
    fs.release()
