"""Enhanced unified camera model (Khomutenko, Garcia and Martinet, RA-L 2016)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ..base import CameraModel
from ..registry import register


@register
@dataclass(frozen=True, kw_only=True)
class EnhancedUnified(CameraModel):
    r"""EUCM: fx, fy, cx, cy, alpha, beta.

    Projection: :math:`d = \sqrt{\beta(x^2 + y^2) + z^2}`,
    :math:`u = f_x x / (\alpha d + (1-\alpha) z) + c_x` (same for v).

    Unprojection (closed form):
    :math:`m_z = (1 - \beta\alpha^2 r^2) / (\alpha\sqrt{1 - (2\alpha-1)\beta r^2} + 1 - \alpha)`,
    ray :math:`\propto (m_x, m_y, m_z)`.

    Valid domain: :math:`\theta \le \theta_{max}` where the radial map stops increasing (beyond
    90 degrees, and beyond 180 degrees field of view for :math:`\alpha \le 0.5`); pixels with
    :math:`r \le r(\theta_{max})`, i.e. :math:`r^2 \le 1/(\beta(2\alpha-1))` for
    :math:`\alpha > 0.5`. Parameters: :math:`\alpha \in [0, 1]`, :math:`\beta > 0`.
    """

    name: ClassVar[str] = "enhanced_unified"
    param_names: ClassVar[tuple[str, ...]] = ("fx", "fy", "cx", "cy", "alpha", "beta")

    fx: float
    fy: float
    cx: float
    cy: float
    alpha: float
    beta: float
    width: int
    height: int

    def _check_model(self) -> None:
        if not 0.0 <= self.alpha <= 1.0:
            raise ValueError(f"EnhancedUnified.alpha: expected a value in [0, 1], got {self.alpha}")
        if self.beta <= 0:
            raise ValueError(f"EnhancedUnified.beta: expected > 0, got {self.beta}")

    def _rho(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.sqrt(self.beta * np.sin(theta) ** 2 + np.cos(theta) ** 2)

    def _radius(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        a = self.alpha
        return np.sin(theta) / (a * self._rho(theta) + (1 - a) * np.cos(theta))

    def _radius_derivative(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        a, b = self.alpha, self.beta
        s, c = np.sin(theta), np.cos(theta)
        rho = self._rho(theta)
        den = a * rho + (1 - a) * c
        dden = a * (b - 1) * s * c / rho - (1 - a) * s
        return (c * den - s * dden) / den**2

    def _lift(self, mx, my, r):  # noqa: D102 - closed form above
        a, b = self.alpha, self.beta
        r2 = r * r
        mz = (1 - b * a * a * r2) / (a * np.sqrt(np.maximum(1 - (2 * a - 1) * b * r2, 0.0)) + 1 - a)
        return np.stack([mx, my, mz], axis=-1)
