"""Pinhole camera."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ..base import CameraModel
from ..registry import register


@register
@dataclass(frozen=True, kw_only=True)
class Pinhole(CameraModel):
    r"""Ideal perspective camera.

    Projection: :math:`u = f_x x / z + c_x,\ v = f_y y / z + c_y`, i.e. :math:`r(\theta) = \tan\theta`.

    Unprojection: :math:`(m_x, m_y, 1) / \|(m_x, m_y, 1)\|`.

    Valid domain: rays with :math:`z > 0` (``theta < pi/2``); every finite pixel.
    """

    name: ClassVar[str] = "pinhole"
    param_names: ClassVar[tuple[str, ...]] = ("fx", "fy", "cx", "cy")

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def _radius(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(theta < np.pi / 2, np.tan(theta), np.nan)

    def _radius_derivative(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(theta < np.pi / 2, 1.0 / np.cos(theta) ** 2, np.nan)

    def _lift(self, mx, my, r):  # noqa: D102 - closed form
        return np.stack([mx, my, np.ones_like(mx)], axis=-1)
