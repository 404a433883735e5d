"""Basalt calibration JSON (``value0`` with ``T_imu_cam``, ``intrinsics``, ``resolution``).

``camera_type`` and parameter names: ``kb4`` (fx fy cx cy k1 k2 k3 k4), ``ds`` (fx fy cx cy xi
alpha), ``eucm`` (fx fy cx cy alpha beta), ``ucm`` (fx fy cx cy alpha; converted to Mei's xi),
``pinhole`` (fx fy cx cy). ``T_imu_cam`` maps camera to IMU (``imu_from_cam``).
"""

from __future__ import annotations

import numpy as np

from ..models import Unified
from ..transforms import make_transform, quat_to_matrix
from ._fields import Fields
from .rig import Rig

_TYPES = {
    "kb4": ("kannala_brandt", ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")),
    "ds": ("double_sphere", ("fx", "fy", "cx", "cy", "xi", "alpha")),
    "eucm": ("enhanced_unified", ("fx", "fy", "cx", "cy", "alpha", "beta")),
    "ucm": ("unified", ("fx", "fy", "cx", "cy", "alpha")),
    "pinhole": ("pinhole", ("fx", "fy", "cx", "cy")),
}


def looks_like(doc: object) -> bool:
    return isinstance(doc, dict) and isinstance(doc.get("value0"), dict) and "intrinsics" in doc["value0"]


def read_doc(doc: object, source: str) -> Rig:
    f = Fields(source)
    root = f.mapping(f.get(doc, "value0", ""), "value0")
    intrinsics = f.get(root, "intrinsics", "value0")
    resolution = f.get(root, "resolution", "value0")
    if not isinstance(intrinsics, list) or not intrinsics:
        raise f.fail("value0.intrinsics", "expected a non-empty list of cameras")
    if not isinstance(resolution, list) or len(resolution) != len(intrinsics):
        raise f.fail("value0.resolution", f"expected a list of {len(intrinsics)} [width, height] pairs")
    poses = root.get("T_imu_cam")
    if poses is not None and (not isinstance(poses, list) or len(poses) != len(intrinsics)):
        raise f.fail("value0.T_imu_cam", f"expected a list of {len(intrinsics)} poses")
    cameras, extr = [], []
    for i, entry in enumerate(intrinsics):
        field = f"value0.intrinsics[{i}]"
        ctype = f.string(f.get(entry, "camera_type", field), f"{field}.camera_type")
        if ctype not in _TYPES:
            raise f.fail(f"{field}.camera_type",
                         f"unknown camera type {ctype!r}; expected one of {', '.join(_TYPES)}")
        name, keys = _TYPES[ctype]
        values = f.mapping(f.get(entry, "intrinsics", field), f"{field}.intrinsics")
        params = {k: f.number(f.get(values, k, f"{field}.intrinsics"), f"{field}.intrinsics.{k}")
                  for k in keys}
        wh = f.numbers(resolution[i], f"value0.resolution[{i}]", 2)
        size = dict(width=f.size(wh[0], f"value0.resolution[{i}][0]"),
                    height=f.size(wh[1], f"value0.resolution[{i}][1]"))
        if ctype == "ucm":
            try:
                cameras.append(Unified.from_alpha(**params, **size))
            except ValueError as exc:
                raise f.fail(f"{field}.intrinsics", str(exc)) from None
        else:
            cameras.append(f.camera(name, f"{field}.intrinsics", **params, **size))
        extr.append(None if poses is None else _pose(f, poses[i], f"value0.T_imu_cam[{i}]"))
    names = tuple(f"cam{i}" for i in range(len(cameras)))
    return Rig(tuple(cameras), names, tuple(extr), reference="imu" if poses is not None else "none")


def _pose(f: Fields, entry: object, field: str) -> np.ndarray:
    t = [f.number(f.get(entry, k, field), f"{field}.{k}") for k in ("px", "py", "pz")]
    q = [f.number(f.get(entry, k, field), f"{field}.{k}") for k in ("qx", "qy", "qz", "qw")]
    try:
        return make_transform(quat_to_matrix(q), t)
    except ValueError as exc:
        raise f.fail(field, str(exc).split(": ", 1)[-1]) from None
