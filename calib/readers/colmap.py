"""COLMAP ``cameras.txt``: ``CAMERA_ID MODEL WIDTH HEIGHT PARAMS...`` per line.

COLMAP puts the centre of the top-left pixel at (0.5, 0.5); OpenCV (and this package) at (0, 0),
so ``cx, cy`` are read as ``cx - 0.5, cy - 0.5``.
"""

from __future__ import annotations

from ._fields import Fields
from .rig import Rig

# COLMAP model -> (registry name, parameter names in COLMAP's order)
_MODELS = {
    "SIMPLE_PINHOLE": ("pinhole", ("f", "cx", "cy")),
    "PINHOLE": ("pinhole", ("fx", "fy", "cx", "cy")),
    "OPENCV_FISHEYE": ("kannala_brandt", ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")),
    "SIMPLE_RADIAL_FISHEYE": ("kannala_brandt", ("f", "cx", "cy", "k1")),
    "RADIAL_FISHEYE": ("kannala_brandt", ("f", "cx", "cy", "k1", "k2")),
    "EUCM": ("enhanced_unified", ("fx", "fy", "cx", "cy", "alpha", "beta")),
    # The equidistant model without distortion: Kannala-Brandt with k = 0.
    "SIMPLE_FISHEYE": ("kannala_brandt", ("f", "cx", "cy")),
    "FISHEYE": ("kannala_brandt", ("fx", "fy", "cx", "cy")),
}


def looks_like(text: str) -> bool:
    for line in text.splitlines():
        s = line.strip()
        if s and not s.startswith("#"):
            parts = s.split()
            return len(parts) >= 4 and parts[0].isdigit() and parts[1].isupper()
    return False


def read(text: str, source: str) -> Rig:
    """Every supported camera of the file; lines of unsupported models are skipped, and asking
    for one of those cameras is the error (``Rig.unsupported``)."""
    f = Fields(source)
    cameras, names, unsupported = [], [], {}
    for lineno, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        parts = s.split()
        field = f"line {lineno}"
        if len(parts) < 4:
            raise f.fail(field, "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS...")
        cam_id, model = parts[0], parts[1]
        if model not in _MODELS:
            unsupported[cam_id] = f.fail(
                f"{field}.MODEL", f"unknown or unsupported camera model {model[:40]!r}; "
                f"expected one of {', '.join(_MODELS)}")
            continue
        name, keys = _MODELS[model]
        values = parts[4:]
        if len(values) != len(keys):
            raise f.fail(f"{field}.PARAMS", f"expected {len(keys)} numbers for {model}, got {len(values)}")
        p = {k: f.number(v, f"{field}.{k}") for k, v in zip(keys, values, strict=True)}
        if "f" in p:
            p["fx"] = p["fy"] = p.pop("f")
        p["cx"] -= 0.5
        p["cy"] -= 0.5
        cameras.append(f.camera(name, field, **p, width=f.size(parts[2], f"{field}.WIDTH"),
                                height=f.size(parts[3], f"{field}.HEIGHT")))
        names.append(cam_id)
    if not cameras:
        if unsupported:
            raise next(iter(unsupported.values()))
        raise f.fail("(file)", "expected at least one camera line")
    return Rig(tuple(cameras), tuple(names), tuple(None for _ in cameras), reference="none",
               unsupported=unsupported)
