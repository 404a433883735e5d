"""Unified camera model (Geyer and Daniilidis; Mei and Rives)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ..base import CameraModel
from ..registry import register


@register
@dataclass(frozen=True, kw_only=True)
class Unified(CameraModel):
    r"""UCM in Mei's form: fx, fy, cx, cy, xi (Kalibr ``omni`` without distortion).

    Projection: :math:`u = f_x x / (z + \xi\|X\|) + c_x` (same for v).
    Basalt's ``ucm`` uses :math:`\alpha = \xi / (1 + \xi)` and focal lengths
    :math:`f_\alpha = f_\xi / (1 + \xi)`; :meth:`from_alpha` converts.

    Unprojection (closed form): :math:`k = (\xi + \sqrt{1 + (1 - \xi^2) r^2}) / (1 + r^2)`,
    ray :math:`= (k m_x, k m_y, k - \xi)`.

    Valid domain: :math:`\theta \le \theta_{max}` with
    :math:`\cos\theta_{max} = -\min(\xi, 1/\xi)`: for :math:`\xi > 1` the radial map folds
    there, for :math:`\xi \le 1` the denominator :math:`\cos\theta + \xi` vanishes (the pixel
    radius goes to infinity); pixels with :math:`r^2 \le 1/(\xi^2 - 1)` for :math:`\xi > 1`,
    every pixel otherwise. Parameter: :math:`\xi \ge 0`.
    """

    name: ClassVar[str] = "unified"
    param_names: ClassVar[tuple[str, ...]] = ("fx", "fy", "cx", "cy", "xi")

    fx: float
    fy: float
    cx: float
    cy: float
    xi: float
    width: int
    height: int

    @classmethod
    def from_alpha(cls, *, fx: float, fy: float, cx: float, cy: float, alpha: float,
                   width: int, height: int) -> Unified:
        """Build from Basalt's ``ucm`` parameters (``alpha`` in ``[0, 1)``)."""
        if not 0.0 <= alpha < 1.0:
            raise ValueError(f"Unified.alpha: expected a value in [0, 1), got {alpha}")
        xi = alpha / (1.0 - alpha)
        return cls(fx=fx * (1 + xi), fy=fy * (1 + xi), cx=cx, cy=cy, xi=xi,
                   width=width, height=height)

    def _check_model(self) -> None:
        if self.xi < 0:
            raise ValueError(f"Unified.xi: expected >= 0, got {self.xi}")

    def _radius(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.sin(theta) / (np.cos(theta) + self.xi)

    def _radius_derivative(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        c = np.cos(theta)
        return (1.0 + self.xi * c) / (c + self.xi) ** 2

    def _lift(self, mx, my, r):  # noqa: D102 - closed form above
        xi = self.xi
        r2 = r * r
        k = (xi + np.sqrt(np.maximum(1 + (1 - xi * xi) * r2, 0.0))) / (1 + r2)
        return np.stack([k * mx, k * my, k - xi], axis=-1)
