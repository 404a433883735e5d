"""OpenCV FileStorage calibration files (YAML with ``%YAML:1.0`` or ``%YAML 1.2`` headers, XML).

Read and written with ``cv2.FileStorage`` itself, never with a YAML parser: OpenCV's YAML dialect
(``!!opencv-matrix``) is not standard YAML.

Fields read: ``image_width``, ``image_height``, ``camera_matrix`` (3x3), ``distortion_coefficients``
(4 numbers with ``fisheye_model: 1`` for cv2.fisheye / Kannala-Brandt). Files written by
:func:`write` also carry ``camera_model`` (a registry name) and every parameter as a scalar
node, so that any model round-trips.
"""

from __future__ import annotations

import os
import tempfile

import cv2
import numpy as np

from ..base import CameraModel
from ..models import KannalaBrandt, Pinhole
from ..registry import model_class
from ._fields import Fields
from .rig import Rig

#: A calibration matrix has a handful of elements; more is not a calibration.
_MAX_ELEMENTS = 64

# cv2 reports parse errors as cv2.error, and some malformed XML as SystemError.
_CV2_ERRORS = (cv2.error, SystemError)


def _node_value(node: cv2.FileNode):
    if node.empty() or node.isNone():
        return None
    if node.isMap():
        return _matrix(node)
    if node.isInt() or node.isReal():
        return node.real()
    if node.isString():
        return node.string()
    if node.isSeq():
        return [node.at(i).real() for i in range(node.size())]
    return None


def _matrix(node: cv2.FileNode) -> np.ndarray | None:
    """Elements of an ``!!opencv-matrix`` node, checked before they are read.

    ``FileNode.mat()`` is not used: on a matrix node whose ``rows``/``cols`` disagree with its
    ``data`` (a truncated or hand-edited file) OpenCV 5.0 corrupts the heap and the process
    aborts later; found by fuzzing the readers.
    """
    rows, cols, data = node.getNode("rows"), node.getNode("cols"), node.getNode("data")
    if not (rows.isInt() and cols.isInt() and data.isSeq()):
        return None
    n_rows, n_cols = int(rows.real()), int(cols.real())
    if n_rows < 0 or n_cols < 0 or data.size() != n_rows * n_cols or data.size() > _MAX_ELEMENTS:
        return None
    # The shape agrees with the data, so mat() is safe (and linear; FileNode.at(i) in a loop is
    # quadratic).
    m = node.mat()
    if m is None or m.size != n_rows * n_cols:
        return None
    return np.asarray(m, dtype=np.float64).reshape(n_rows, n_cols)


def read(text: str, source: str) -> Rig:
    f = Fields(source)
    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    except _CV2_ERRORS as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "parse error"
        raise f.fail("(file)", f"not a readable OpenCV FileStorage file: {msg}") from None
    try:
        if not fs.isOpened():
            raise f.fail("(file)", "not a readable OpenCV FileStorage file")
        root = fs.root()

        def get(key: str, required: bool = True):
            try:
                node = root.getNode(key)
                present = not (node.empty() or node.isNone())
                value = _node_value(node) if present else None
            except _CV2_ERRORS:
                present, value = True, None
            if present and value is None:
                raise f.fail(key, "expected a number, a string or a well-formed !!opencv-matrix")
            if value is None and required:
                raise f.fail(key, "missing")
            return value

        width = f.size(get("image_width"), "image_width")
        height = f.size(get("image_height"), "image_height")
        model = get("camera_model", required=False)
        k_node = get("camera_matrix", required=False)
        d_node = get("distortion_coefficients", required=False)
        fisheye = get("fisheye_model", required=False)
        if model is not None:
            model = f.string(model, "camera_model")
            cls = model_class_or_fail(f, model)
            params = {}
            for name in cls.param_names:
                value = get(name, required=False)
                if value is None:
                    value = _from_matrices(f, name, k_node, d_node)
                params[name] = f.number(value, name)
            camera = f.camera(model, "camera_model", **params, width=width, height=height)
        else:
            if k_node is None:
                raise f.fail("camera_matrix", "missing")
            k = f.numbers(k_node, "camera_matrix", 9)
            _check_camera_matrix(f, k)
            d = [] if d_node is None else f.numbers(d_node, "distortion_coefficients")
            intr = dict(fx=k[0], fy=k[4], cx=k[2], cy=k[5], width=width, height=height)
            if fisheye is not None and f.number(fisheye, "fisheye_model") == 1:
                if len(d) != 4:
                    raise f.fail("distortion_coefficients", f"expected 4 numbers, got {len(d)}")
                camera = f.camera("kannala_brandt", "camera_matrix", **intr,
                                  k1=d[0], k2=d[1], k3=d[2], k4=d[3])
            elif not any(d):
                camera = f.camera("pinhole", "camera_matrix", **intr)
            else:
                raise f.fail(
                    "distortion_coefficients",
                    "non-zero distortion without fisheye_model: 1; only the fisheye "
                    "(Kannala-Brandt) distortion is supported",
                )
    finally:
        fs.release()
    name = os.path.splitext(os.path.basename(source))[0]
    return Rig(cameras=(camera,), names=(name,), extrinsics=(None,), reference="none")


def _check_camera_matrix(f: Fields, k: list[float]) -> None:
    """``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` with no skew ``s`` (no model here has one: a
    skew of 1 % of fx ignored would be pixels of error)."""
    if abs(k[1]) > 1e-9 * max(abs(k[0]), 1.0):
        raise f.fail("camera_matrix", f"non-zero skew {k[1]!r} (element [0][1]); the camera "
                     "models here have none")
    if any(abs(k[i]) > 1e-12 for i in (3, 6, 7)) or abs(k[8] - 1.0) > 1e-12:
        raise f.fail("camera_matrix", "expected the form [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], "
                     f"got last rows {[k[3:6], k[6:9]]}")


def model_class_or_fail(f: Fields, model: str) -> type[CameraModel]:
    try:
        return model_class(model)
    except ValueError as exc:
        raise f.fail("camera_model", str(exc).split(": ", 1)[-1]) from None


def _from_matrices(f: Fields, name: str, k_node, d_node):
    kpos = {"fx": 0, "fy": 4, "cx": 2, "cy": 5}
    if name in kpos and k_node is not None:
        return f.numbers(k_node, "camera_matrix", 9)[kpos[name]]
    if name in ("k1", "k2", "k3", "k4") and d_node is not None:
        d = f.numbers(d_node, "distortion_coefficients")
        idx = int(name[1]) - 1
        if idx < len(d):
            return d[idx]
    raise f.fail(name, "missing")


def write(camera: CameraModel, path: str | os.PathLike) -> None:
    """Write ``camera`` as an OpenCV FileStorage file (YAML or XML by the file's extension).

    Kannala-Brandt and pinhole cameras are written in the layout ``cv2.fisheye`` users expect
    (``camera_matrix``, ``distortion_coefficients``, ``fisheye_model``); every model also gets
    ``camera_model`` and its parameters as named scalars.
    """
    path = os.fspath(path)
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    try:
        fs.write("image_width", int(camera.width))
        fs.write("image_height", int(camera.height))
        fs.write("camera_model", camera.name)
        if isinstance(camera, KannalaBrandt | Pinhole):
            fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
            fs.write("camera_matrix", np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], float))
        if isinstance(camera, KannalaBrandt):
            fs.write("fisheye_model", 1)
            d = np.array([[camera.k1], [camera.k2], [camera.k3], [camera.k4]], float)
            fs.write("distortion_coefficients", d)
        for name, value in camera.params.items():
            fs.write(name, float(value))
    finally:
        fs.release()


def dumps(camera: CameraModel, suffix: str = ".yaml") -> str:
    """The text :func:`write` would write."""
    with tempfile.TemporaryDirectory() as tmp:
        p = os.path.join(tmp, "calib" + suffix)
        write(camera, p)
        with open(p, encoding="utf-8") as fh:
            return fh.read()
