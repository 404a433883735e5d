"""ROS ``sensor_msgs/CameraInfo`` YAML, as ``camera_calibration_parsers`` writes it.

``distortion_model: equidistant`` (and the older ``camera_model: fisheye``) is Kannala-Brandt with
``distortion_coefficients.data = [k1, k2, k3, k4]``; ``plumb_bob`` with all-zero coefficients is
a pinhole camera.
"""

from __future__ import annotations

from ._fields import Fields
from .rig import Rig

_KB = {"equidistant", "fisheye", "kannala_brandt"}
_PINHOLE = {"plumb_bob", "rational_polynomial", "none", "pinhole"}


def looks_like(doc: object) -> bool:
    return isinstance(doc, dict) and "camera_matrix" in doc


def read_doc(doc: object, source: str) -> Rig:
    f = Fields(source)
    doc = f.mapping(doc, "(top level)")
    width = f.size(f.get(doc, "image_width", ""), "image_width")
    height = f.size(f.get(doc, "image_height", ""), "image_height")
    k = f.numbers(f.get(f.get(doc, "camera_matrix", ""), "data", "camera_matrix"),
                  "camera_matrix.data", 9)
    if "distortion_model" in doc:
        field = "distortion_model"
    elif "camera_model" in doc:
        field = "camera_model"
    else:
        raise f.fail("distortion_model", "missing")
    model = f.string(doc[field], field)
    d_entry = doc.get("distortion_coefficients", {"data": []})
    d = f.numbers(f.get(d_entry, "data", "distortion_coefficients"), "distortion_coefficients.data")
    intr = dict(fx=k[0], fy=k[4], cx=k[2], cy=k[5], width=width, height=height)
    if model in _KB:
        if len(d) != 4:
            raise f.fail("distortion_coefficients.data", f"expected 4 numbers, got {len(d)}")
        camera = f.camera("kannala_brandt", "camera_matrix", **intr,
                          k1=d[0], k2=d[1], k3=d[2], k4=d[3])
    elif model in _PINHOLE and not any(d):
        camera = f.camera("pinhole", "camera_matrix", **intr)
    else:
        raise f.fail(field, f"unsupported model {model!r}; expected equidistant or fisheye")
    name = doc.get("camera_name", "camera")
    return Rig((camera,), (str(name),), (None,), reference="none")
