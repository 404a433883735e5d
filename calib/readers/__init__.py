"""Calibration-file readers and writers.

:func:`load` detects the format from the file's name and content:

=================  ======================================================================
format             detected by
=================  ======================================================================
``opencv``         ``.xml``, text starting with ``%YAML`` (OpenCV 4 ``%YAML:1.0``, OpenCV 5
                   ``%YAML 1.2``), or FileStorage JSON (``"type_id": "opencv-matrix"``); read
                   with ``cv2.FileStorage``
``kalibr``         YAML with ``cam0``, ``cam1``... entries
``ros``            YAML with ``camera_matrix`` (sensor_msgs/CameraInfo)
``basalt``         JSON with ``value0.intrinsics``
``woodscape``      JSON with ``intrinsic``
``aria``           JSON with ``CameraCalibrations`` (Project Aria factory calibration), or
                   Aria camera summaries (``{label: {projection_params, ...}}``)
``colmap``         text lines ``CAMERA_ID MODEL WIDTH HEIGHT PARAMS...`` (``cameras.txt``)
=================  ======================================================================

Every malformed input raises :class:`~fisheyemotion.calib.CalibrationError` (a ValueError)
naming the file and the field.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import yaml

from ..base import CameraModel
from ..errors import CalibrationError
from . import aria, basalt, colmap, kalibr, opencv, ros, woodscape
from .rig import Rig

FORMATS = ("opencv", "kalibr", "ros", "basalt", "woodscape", "aria", "colmap")

#: Characters: calibration files are a few KB; larger text is refused before it is parsed.
MAX_FILE_SIZE = 1 << 20


def parse(text: str, source: str = "<string>", *, format: str | None = None) -> Rig:
    """Parse calibration text; ``format`` forces one of :data:`FORMATS`, else it is detected."""
    if format is not None and format not in FORMATS:
        raise ValueError(f"format: expected one of {', '.join(FORMATS)}, got {format!r}")
    if len(text) > MAX_FILE_SIZE:
        raise CalibrationError("(file)", f"{len(text)} characters; a calibration file has a "
                               f"few thousand (limit {MAX_FILE_SIZE})", source=source)
    try:
        return _parse(text, source, format)
    except RecursionError:
        raise CalibrationError("(file)", "nested too deeply to be a calibration file",
                               source=source) from None


def _is_opencv_json(text: str) -> bool:
    return '"opencv-matrix"' in text or '"type_id"' in text


def _parse(text: str, source: str, format: str | None) -> Rig:
    stripped = text.lstrip("\ufeff \t\r\n")
    if format == "opencv" or (format is None and (
            stripped.startswith("%YAML") or stripped.startswith("<?xml")
            or stripped.startswith("<opencv_storage>")
            or (stripped.startswith("{") and _is_opencv_json(stripped)))):
        return opencv.read(text, source)
    if format == "colmap" or (format is None and colmap.looks_like(text)):
        return colmap.read(text, source)
    if stripped.startswith("{") or format in ("basalt", "woodscape", "aria"):
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as exc:
            raise CalibrationError("(file)", f"not valid JSON: {exc}", source=source) from None
        readers = {"basalt": basalt, "woodscape": woodscape, "aria": aria}
        for name, reader in readers.items():
            if format == name or (format is None and reader.looks_like(doc)):
                return reader.read_doc(doc, source)
        raise CalibrationError("(top level)", "expected Basalt 'value0', WoodScape 'intrinsic' "
                               "or Aria 'CameraCalibrations'", source=source)
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise CalibrationError("(file)", f"not valid YAML: {str(exc).splitlines()[0]}",
                               source=source) from None
    for name, reader in (("kalibr", kalibr), ("ros", ros)):
        if format == name or (format is None and reader.looks_like(doc)):
            return reader.read_doc(doc, source)
    raise CalibrationError(
        "(top level)",
        "unrecognised calibration format; expected OpenCV FileStorage, Kalibr camchain, ROS "
        "CameraInfo, Basalt, WoodScape or Project Aria JSON, or COLMAP cameras.txt",
        source=source,
    )


def load_rig(path: str | os.PathLike, *, format: str | None = None) -> Rig:
    """All cameras of a calibration file with their extrinsics.

    Parameters
    ----------
    path : str or path-like
    format : str, optional
        One of :data:`FORMATS`; detected when omitted.

    Returns
    -------
    Rig
    """
    p = Path(path)
    try:
        if p.stat().st_size > MAX_FILE_SIZE:
            raise CalibrationError("(file)", f"{p.stat().st_size} bytes; a calibration file has "
                                   f"a few thousand (limit {MAX_FILE_SIZE})", source=str(p))
        raw = p.read_bytes()
    except FileNotFoundError:
        raise CalibrationError("path", "no such file", source=str(p)) from None
    except OSError as exc:
        raise CalibrationError("(file)", f"cannot be read: {exc}", source=str(p)) from None
    if p.name == "cameras.bin" or raw[:8].count(b"\x00") >= 4:
        raise CalibrationError("(file)", "a binary file (a binary COLMAP model?); convert it "
                               "with 'colmap model_converter --output_type TXT' and give "
                               "cameras.txt", source=str(p))
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CalibrationError("(file)", f"cannot be read as UTF-8 text: {exc}", source=str(p)) from None
    return parse(text, str(p), format=format)


def load(path: str | os.PathLike, camera: int | str = 0, *, format: str | None = None) -> CameraModel:
    """The camera model of a calibration file.

    Parameters
    ----------
    path : str or path-like
    camera : int or str, default 0
        Index, or name (``cam1``, a COLMAP camera id, WoodScape's ``FV``...), in multi-camera files.
    format : str, optional
        One of :data:`FORMATS`; detected when omitted.
    """
    return load_rig(path, format=format)[camera]


def save_opencv(camera: CameraModel, path: str | os.PathLike) -> None:
    """Write an OpenCV FileStorage file (``.yaml``/``.yml`` or ``.xml``)."""
    opencv.write(camera, path)


def save_kalibr(rig_or_camera: Rig | CameraModel, path: str | os.PathLike) -> None:
    """Write a Kalibr camchain YAML file."""
    kalibr.write(rig_or_camera, path)


__all__ = ["FORMATS", "Rig", "load", "load_rig", "parse", "save_kalibr", "save_opencv"]
