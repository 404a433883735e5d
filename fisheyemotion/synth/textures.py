"""Photographic textures shipped with scikit-image (no download), as float32 BGR images."""

from __future__ import annotations

from functools import lru_cache

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


@lru_cache(maxsize=None)
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


def sample(name: str, u: NDArray[np.float64], v: NDArray[np.float64],
           texel: float) -> NDArray[np.float32]:
    """Colours at surface coordinates ``(u, v)`` metres, tiling the texture with ``texel`` metres
    per texel (nearest texel; the renderer supersamples)."""
    tex = texture(name)
    h, w = tex.shape[:2]
    col = np.floor(u / texel).astype(np.int64) % w
    row = np.floor(-v / texel).astype(np.int64) % h
    return tex[row, col]
