"""Calibration-file readers and writers.

:func:`load` detects the format from the file's name and content:

=================  ======================================================================
format             detected by
=================  ======================================================================
``opencv``         ``.xml``, or text starting with ``%YAML`` (OpenCV 4 ``%YAML:1.0``, OpenCV 5
                   ``%YAML 1.2``); read with ``cv2.FileStorage``
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


def parse(text: str, source: str = "<string>", *, format: str | None = None) -> Rig:
    """Parse calibration text; ``format`` forces one of :data:`FORMATS`, else it is detected."""
    if format is not None and format not in FORMATS:
        raise ValueError(f"format: expected one of {', '.join(FORMATS)}, got {format!r}")
    stripped = text.lstrip("\ufeff \t\r\n")
    if format == "opencv" or (format is None and (
            stripped.startswith("%YAML") or stripped.startswith("<?xml")
            or stripped.startswith("<opencv_storage>"))):
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
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CalibrationError("path", "no such file", source=str(p)) from None
    except (OSError, UnicodeDecodeError) as exc:
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
