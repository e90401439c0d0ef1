"""Reading and writing a camera calibration as an OpenCV FileStorage file (``data/camera.xml``).

The file holds a map ``camera`` with ``camera_matrix`` (3×3), ``distortion_coefficients`` (12×1), ``flags``
(int) and ``imageSize`` (two ints: width height). This module only moves those four values between the file
and numpy; ``helpers.camera.Camera.from_xml`` / ``to_xml`` check them and build the model.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["read_camera_xml", "write_camera_xml"]


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

    path = Path(path)
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
    """Write a calibration in the format :func:`read_camera_xml` reads (12 distortion coefficients)."""
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
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
