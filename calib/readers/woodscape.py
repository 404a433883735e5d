"""WoodScape calibration JSON: ``intrinsic`` (``radial_poly``) and ``extrinsic``.

The extrinsic is camera-to-vehicle (``vehicle_from_cam``, ISO 8855 vehicle frame: x forward,
y left, z up) with ``quaternion`` in ``(x, y, z, w)`` order (scipy's, as WoodScape's own
``projection.py`` reads it) and ``translation`` in metres.
"""

from __future__ import annotations

from ..transforms import make_transform, quat_to_matrix
from ._fields import Fields
from .rig import Rig


def looks_like(doc: object) -> bool:
    return isinstance(doc, dict) and "intrinsic" in doc


def read_doc(doc: object, source: str) -> Rig:
    f = Fields(source)
    intr = f.mapping(f.get(doc, "intrinsic", ""), "intrinsic")
    model = f.string(f.get(intr, "model", "intrinsic"), "intrinsic.model")
    if model != "radial_poly":
        raise f.fail("intrinsic.model", f"unknown model {model!r}; expected 'radial_poly'")
    order = intr.get("poly_order", 4)
    if f.number(order, "intrinsic.poly_order") != 4:
        raise f.fail("intrinsic.poly_order", f"expected 4, got {order!r}")
    p = {k: f.number(f.get(intr, k, "intrinsic"), f"intrinsic.{k}")
         for k in ("k1", "k2", "k3", "k4", "cx_offset", "cy_offset")}
    p["aspect_ratio"] = f.number(intr.get("aspect_ratio", 1.0), "intrinsic.aspect_ratio")
    camera = f.camera("radial_poly", "intrinsic", **p,
                      width=f.size(f.get(intr, "width", "intrinsic"), "intrinsic.width"),
                      height=f.size(f.get(intr, "height", "intrinsic"), "intrinsic.height"))
    extr = None
    if "extrinsic" in doc:
        e = f.mapping(doc["extrinsic"], "extrinsic")
        q = f.numbers(f.get(e, "quaternion", "extrinsic"), "extrinsic.quaternion", 4)
        t = f.numbers(f.get(e, "translation", "extrinsic"), "extrinsic.translation", 3)
        try:
            extr = make_transform(quat_to_matrix(q), t)
        except ValueError as exc:
            raise f.fail("extrinsic.quaternion", str(exc).split(": ", 1)[-1]) from None
    name = doc.get("name", "camera")
    return Rig((camera,), (str(name),), (extr,), reference="vehicle" if extr is not None else "none")
