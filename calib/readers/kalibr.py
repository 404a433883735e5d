"""Kalibr camchain YAML (``camchain.yaml``, ``camchain-imucam.yaml``).

Kalibr's own parameter orders (``intrinsics``):

============================  =====================================
camera_model / distortion     intrinsics
============================  =====================================
pinhole / equidistant         ``[fu, fv, pu, pv]`` + 4 ``distortion_coeffs`` (Kannala-Brandt)
pinhole / none                ``[fu, fv, pu, pv]``
omni / none                   ``[xi, fu, fv, pu, pv]`` (unified)
ds / none                     ``[xi, alpha, fu, fv, pu, pv]``
eucm / none                   ``[alpha, beta, fu, fv, pu, pv]``
============================  =====================================

Extrinsics: ``T_cam_imu`` maps IMU to camera (``cam_from_imu``); ``T_cn_cnm1`` maps camera n-1
to camera n.
"""

from __future__ import annotations

import os
import re

import numpy as np
import yaml

from ..base import CameraModel
from ..transforms import invert_transform
from ._fields import Fields
from .rig import Rig

_CAM_KEY = re.compile(r"^cam(\d+)$")

# (camera_model, distortion_model) -> (registry name, intrinsics names, distortion names)
_LAYOUTS: dict[tuple[str, str], tuple[str, tuple[str, ...], tuple[str, ...]]] = {
    ("pinhole", "equidistant"): ("kannala_brandt", ("fx", "fy", "cx", "cy"), ("k1", "k2", "k3", "k4")),
    ("pinhole", "none"): ("pinhole", ("fx", "fy", "cx", "cy"), ()),
    ("omni", "none"): ("unified", ("xi", "fx", "fy", "cx", "cy"), ()),
    ("ds", "none"): ("double_sphere", ("xi", "alpha", "fx", "fy", "cx", "cy"), ()),
    ("eucm", "none"): ("enhanced_unified", ("alpha", "beta", "fx", "fy", "cx", "cy"), ()),
}
_BY_MODEL = {v[0]: (k, v[1], v[2]) for k, v in _LAYOUTS.items()}


def looks_like(doc: object) -> bool:
    return isinstance(doc, dict) and any(isinstance(k, str) and _CAM_KEY.match(k) for k in doc)


def read_doc(doc: object, source: str) -> Rig:
    f = Fields(source)
    doc = f.mapping(doc, "(top level)")
    keys = sorted(
        (int(m.group(1)), k) for k in doc if isinstance(k, str) and (m := _CAM_KEY.match(k))
    )
    if not keys:
        raise f.fail("cam0", "missing")
    if [n for n, _ in keys] != list(range(len(keys))):
        raise f.fail(keys[-1][1], "expected cameras cam0, cam1, ... numbered without gaps")
    cameras, names, chain, imu = [], [], [], []
    for _, key in keys:
        entry = f.mapping(doc[key], key)
        cameras.append(_camera(f, entry, key))
        names.append(key)
        chain.append(f.transform(entry["T_cn_cnm1"], f"{key}.T_cn_cnm1")
                     if "T_cn_cnm1" in entry and key != "cam0" else None)
        imu.append(f.transform(entry["T_cam_imu"], f"{key}.T_cam_imu")
                   if "T_cam_imu" in entry else None)
    # cam0_from_camN by chaining T_cn_cnm1 (camN_from_camN-1).
    cam0_from: list[np.ndarray | None] = [np.eye(4)]
    for n in range(1, len(cameras)):
        prev = cam0_from[-1]
        cam0_from.append(None if prev is None or chain[n] is None
                         else prev @ invert_transform(chain[n]))
    if imu[0] is not None:
        imu_from_cam0 = invert_transform(imu[0])
        extr = []
        for n in range(len(cameras)):
            if imu[n] is not None:
                extr.append(invert_transform(imu[n]))
            elif cam0_from[n] is not None:
                extr.append(imu_from_cam0 @ cam0_from[n])
            else:
                extr.append(None)
        return Rig(tuple(cameras), tuple(names), tuple(extr), reference="imu")
    if len(cameras) == 1 or all(t is not None for t in cam0_from):
        return Rig(tuple(cameras), tuple(names), tuple(cam0_from), reference="cam0")
    return Rig(tuple(cameras), tuple(names), tuple(None for _ in cameras), reference="none")


def _camera(f: Fields, entry: dict, key: str) -> CameraModel:
    model = f.string(f.get(entry, "camera_model", key), f"{key}.camera_model")
    dist = entry.get("distortion_model", "none")
    dist = f.string(dist, f"{key}.distortion_model")
    layout = _LAYOUTS.get((model, dist))
    if layout is None:
        if model not in {m for m, _ in _LAYOUTS}:
            known = ", ".join(sorted({m for m, _ in _LAYOUTS}))
            raise f.fail(f"{key}.camera_model", f"unknown camera model {model!r}; expected one of {known}")
        raise f.fail(f"{key}.distortion_model",
                     f"distortion {dist!r} with camera_model {model!r} is not supported")
    name, intr_names, dist_names = layout
    intr = f.numbers(f.get(entry, "intrinsics", key), f"{key}.intrinsics", len(intr_names))
    coeffs = entry.get("distortion_coeffs", [])
    coeffs = f.numbers(coeffs, f"{key}.distortion_coeffs", len(dist_names) if dist_names else None)
    if not dist_names and any(coeffs):
        raise f.fail(f"{key}.distortion_coeffs", f"expected none for distortion_model {dist!r}")
    res = f.numbers(f.get(entry, "resolution", key), f"{key}.resolution", 2)
    params = dict(zip(intr_names, intr, strict=True)) | dict(zip(dist_names, coeffs, strict=True))
    return f.camera(name, f"{key}.intrinsics", **params,
                    width=f.size(res[0], f"{key}.resolution[0]"),
                    height=f.size(res[1], f"{key}.resolution[1]"))


def to_doc(rig: Rig) -> dict:
    """Kalibr camchain dictionary for a rig (extrinsics written as T_cn_cnm1 or T_cam_imu)."""
    doc = {}
    for n, (cam, extr) in enumerate(zip(rig.cameras, rig.extrinsics, strict=True)):
        if cam.name not in _BY_MODEL:
            raise ValueError(f"camera: model {cam.name!r} has no Kalibr camchain form")
        (model, dist), intr_names, dist_names = _BY_MODEL[cam.name]
        entry: dict = {}
        if rig.reference == "imu" and extr is not None:
            entry["T_cam_imu"] = invert_transform(extr).tolist()
        elif n > 0 and rig.reference == "cam0" and extr is not None and rig.extrinsics[n - 1] is not None:
            entry["T_cn_cnm1"] = (invert_transform(extr) @ rig.extrinsics[n - 1]).tolist()
        entry["camera_model"] = model
        entry["distortion_coeffs"] = [float(getattr(cam, k)) for k in dist_names]
        entry["distortion_model"] = dist
        entry["intrinsics"] = [float(getattr(cam, k)) for k in intr_names]
        entry["resolution"] = [int(cam.width), int(cam.height)]
        doc[f"cam{n}"] = entry
    return doc


def write(rig_or_camera: Rig | CameraModel, path: str | os.PathLike) -> None:
    """Write a camera or a rig as a Kalibr camchain YAML file."""
    rig = rig_or_camera if isinstance(rig_or_camera, Rig) else Rig(
        (rig_or_camera,), ("cam0",), (np.eye(4),), reference="cam0")
    with open(path, "w", encoding="utf-8") as fh:
        yaml.safe_dump(to_doc(rig), fh, default_flow_style=None, sort_keys=False)

