"""Photographic textures shipped with scikit-image (no download), as float32 BGR mipmaps.

Sampling (nearest texel of the mipmap level matching a sample's footprint, so that far and grazing
surfaces are prefiltered instead of aliasing, which would make the flow of a static road flicker)
is done per ray in the renderer's kernel, ``_raycast.shade``.
"""

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


@cache
def packed() -> tuple[NDArray[np.float32], NDArray[np.int64], NDArray[np.int64]]:
    """Every texture's mipmaps in one array, for the renderer's kernel.

    Returns
    -------
    data : ndarray of float32, shape (M, 3)
        All levels of all textures (in ``TEXTURES`` order), row-major, one after the other.
    table : ndarray of int64, shape (len(TEXTURES), levels, 3)
        ``(offset, height, width)`` of each level in ``data``; zeros past a texture's last level.
    levels : ndarray of int64, shape (len(TEXTURES),)
        Number of levels of each texture.
    """
    pyramids = [mipmaps(name) for name in TEXTURES]
    table = np.zeros((len(TEXTURES), max(len(p) for p in pyramids), 3), np.int64)
    chunks, offset = [], 0
    for k, levels in enumerate(pyramids):
        for lv, tex in enumerate(levels):
            h, w = tex.shape[:2]
            table[k, lv] = (offset, h, w)
            chunks.append(tex.reshape(-1, 3))
            offset += h * w
    data = np.concatenate(chunks)
    levels = np.array([len(p) for p in pyramids], np.int64)
    for arr in (data, table, levels):
        arr.setflags(write=False)
    return data, table, levels
