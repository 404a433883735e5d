"""Project Aria calibrations: the factory ``device_calibration`` JSON and its per-camera summary.

Factory JSON (as ``.vrs`` recordings and ``projectaria_tools`` write it): ``CameraCalibrations``
is a list of ``{Label, Projection: {Name, Params}, T_Device_Camera: {Translation,
UnitQuaternion: [w, [x, y, z]]}, ConfigData: {ImageWidth, ImageHeight}, ValidRadius?}``.
``FisheyeRadTanThinPrism`` is :class:`~fisheyemotion.calib.Fisheye624` (15 parameters),
``KannalaBrandtK3`` (eye-tracking cameras) is :class:`~fisheyemotion.calib.KannalaBrandt`.

Summary JSON (``camera_calibration_summary.json`` beside the recordings in ``data/real``):
``{label: {model: "CameraModelType.FISHEYE624", projection_params, image_size: [w, h],
valid_radius, T_device_camera_4x4}}``.

Extrinsics are ``device_from_cam`` (the rig's reference ``device``). Image sizes are the
sensor's raw orientation, as the frames are stored.
"""

from __future__ import annotations

import numpy as np

from ..transforms import make_transform, quat_to_matrix
from ._fields import Fields
from .rig import Rig

FISHEYE624_NAMES = ("f", "cx", "cy", "k0", "k1", "k2", "k3", "k4", "k5", "p0", "p1", "s0", "s1",
                    "s2", "s3")
KB3_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")


def looks_like(doc: object) -> bool:
    if not isinstance(doc, dict):
        return False
    if "CameraCalibrations" in doc:
        return True
    return bool(doc) and all(isinstance(v, dict) and "projection_params" in v
                             for v in doc.values())


def _camera(f: Fields, kind: str, params: list[float], width: int, height: int,
            valid_radius: float, field: str):
    if kind in ("FisheyeRadTanThinPrism", "FISHEYE624"):
        if len(params) != 15:
            raise f.fail(f"{field}.params", f"expected 15 FISHEYE624 parameters, got {len(params)}")
        return f.camera("fisheye624", field, **dict(zip(FISHEYE624_NAMES, params, strict=True)),
                        valid_radius=valid_radius, width=width, height=height)
    if kind in ("KannalaBrandtK3", "KANNALA_BRANDT_K3"):
        if len(params) != 8:
            raise f.fail(f"{field}.params", f"expected 8 KannalaBrandtK3 parameters, got {len(params)}")
        return f.camera("kannala_brandt", field, **dict(zip(KB3_NAMES, params, strict=True)),
                        width=width, height=height)
    raise f.fail(f"{field}.model", f"unsupported Aria camera model {kind!r}; expected "
                 "FisheyeRadTanThinPrism (FISHEYE624) or KannalaBrandtK3")


def read_doc(doc: object, source: str) -> Rig:
    f = Fields(source)
    cameras, names, extrinsics = [], [], []
    if "CameraCalibrations" in doc:
        items = doc["CameraCalibrations"]
        if not isinstance(items, list) or not items:
            raise f.fail("CameraCalibrations", "expected a non-empty list")
        for i, item in enumerate(items):
            field = f"CameraCalibrations[{i}]"
            c = f.mapping(item, field)
            proj = f.mapping(f.get(c, "Projection", field), f"{field}.Projection")
            kind = f.string(f.get(proj, "Name", f"{field}.Projection"), f"{field}.Projection.Name")
            params = f.numbers(f.get(proj, "Params", f"{field}.Projection"),
                               f"{field}.Projection.Params")
            conf = f.mapping(f.get(c, "ConfigData", field), f"{field}.ConfigData")
            width = f.size(f.get(conf, "ImageWidth", f"{field}.ConfigData"),
                           f"{field}.ConfigData.ImageWidth")
            height = f.size(f.get(conf, "ImageHeight", f"{field}.ConfigData"),
                            f"{field}.ConfigData.ImageHeight")
            radius = c.get("ValidRadius", conf.get("ValidRadius", 0.0)) or 0.0
            radius = f.number(radius, f"{field}.ValidRadius")
            cameras.append(_camera(f, kind, params, width, height, radius, f"{field}.Projection"))
            names.append(f.string(f.get(c, "Label", field), f"{field}.Label"))
            t = f.mapping(f.get(c, "T_Device_Camera", field), f"{field}.T_Device_Camera")
            extrinsics.append(_se3(f, t, f"{field}.T_Device_Camera"))
    else:
        for label, item in doc.items():
            field = str(label)
            c = f.mapping(item, field)
            kind = f.string(f.get(c, "model", field), f"{field}.model").split(".")[-1]
            params = f.numbers(f.get(c, "projection_params", field), f"{field}.projection_params")
            size = f.numbers(f.get(c, "image_size", field), f"{field}.image_size", 2)
            width, height = (f.size(v, f"{field}.image_size") for v in size)
            radius = c.get("valid_radius") or 0.0
            radius = f.number(radius, f"{field}.valid_radius")
            cameras.append(_camera(f, kind, params, width, height, radius, field))
            names.append(field)
            extrinsics.append(f.transform(c["T_device_camera_4x4"], f"{field}.T_device_camera_4x4")
                              if "T_device_camera_4x4" in c else None)
    return Rig(tuple(cameras), tuple(names), tuple(extrinsics), reference="device")


def _se3(f: Fields, t: dict, field: str) -> np.ndarray:
    trans = f.numbers(f.get(t, "Translation", field), f"{field}.Translation", 3)
    q = f.get(t, "UnitQuaternion", field)
    if (not isinstance(q, list) or len(q) != 2 or not isinstance(q[1], list)):
        raise f.fail(f"{field}.UnitQuaternion", "expected [w, [x, y, z]]")
    w = f.number(q[0], f"{field}.UnitQuaternion[0]")
    xyz = f.numbers(q[1], f"{field}.UnitQuaternion[1]", 3)
    try:
        return make_transform(quat_to_matrix([*xyz, w]), trans)
    except ValueError as exc:
        raise f.fail(f"{field}.UnitQuaternion", str(exc).split(": ", 1)[-1]) from None
