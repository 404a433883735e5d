"""Photographic textures shipped with scikit-image (no download), as float32 BGR images."""

from __future__ import annotations

from functools import cache

import cv2
import numpy as np
from numpy.typing import NDArray
from skimage import data

# name -> (loader, BGR tint for gray images or None for colour ones)
_SOURCES = {
    "gravel": (data.gravel, (0.85, 0.85, 0.85)),
    "grass": (data.grass, (0.45, 0.85, 0.55)),
    "brick": (data.brick, (0.55, 0.65, 0.95)),
    "camera": (data.camera, (0.9, 0.8, 0.7)),
    "coffee": (data.coffee, None),
    "chelsea": (data.chelsea, None),
    "astronaut": (data.astronaut, None),
    "rocket": (data.rocket, None),
}
TEXTURES = tuple(_SOURCES)


@cache
def texture(name: str) -> NDArray[np.float32]:
    """``(H, W, 3)`` float32 BGR in [0, 255] (read-only)."""
    loader, tint = _SOURCES[name]
    img = loader()
    if img.ndim == 2:
        out = np.stack([img * t for t in tint], axis=-1).astype(np.float32)
    else:
        out = cv2.cvtColor(img, cv2.COLOR_RGB2BGR).astype(np.float32)
    out.setflags(write=False)
    return out


@cache
def mipmaps(name: str) -> tuple[NDArray[np.float32], ...]:
    """The texture and its successive 2x box-filtered halvings (down to 4 texels)."""
    levels = [texture(name)]
    while min(levels[-1].shape[:2]) >= 8:
        levels.append(cv2.resize(levels[-1], None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA))
    return tuple(levels)


def sample(name: str, u: NDArray[np.float64], v: NDArray[np.float64], texel: float,
           footprint: NDArray[np.float64] | None = None) -> NDArray[np.float32]:
    """Colours at surface coordinates ``(u, v)`` metres, tiling the texture with ``texel`` metres
    per texel.

    ``footprint`` (metres covered by one sample on the surface) selects the mipmap level, so that
    far and grazing surfaces are prefiltered instead of aliasing (which would make the flow of a
    static road flicker); nearest texel within the level.
    """
    levels = mipmaps(name)
    if footprint is None:
        level = np.zeros(u.shape, np.int64)
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            level = np.floor(np.log2(np.maximum(footprint / texel, 1.0)))
        level = np.clip(np.nan_to_num(level, nan=0.0), 0, len(levels) - 1).astype(np.int64)
    out = np.empty(u.shape + (3,), np.float32)
    for lv in np.unique(level):
        sel = level == lv
        tex = levels[lv]
        h, w = tex.shape[:2]
        scale = texel * 2.0**lv
        col = np.floor(u[sel] / scale).astype(np.int64) % w
        row = np.floor(-v[sel] / scale).astype(np.int64) % h
        out[sel] = tex[row, col]
    return out
