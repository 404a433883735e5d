"""Double sphere camera (Usenko, Demmel and Cremers, 3DV 2018)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ..base import CameraModel
from ..registry import register


@register
@dataclass(frozen=True, kw_only=True)
class DoubleSphere(CameraModel):
    r"""Double sphere model: fx, fy, cx, cy, xi, alpha.

    Projection: :math:`d_1 = \|X\|`, :math:`d_2 = \sqrt{x^2 + y^2 + (\xi d_1 + z)^2}`,
    :math:`u = f_x x / (\alpha d_2 + (1-\alpha)(\xi d_1 + z)) + c_x` (same for v).

    Unprojection (closed form): :math:`r^2 = m_x^2 + m_y^2`,
    :math:`m_z = (1 - \alpha^2 r^2) / (\alpha\sqrt{1 - (2\alpha - 1) r^2} + 1 - \alpha)`,
    :math:`p = \frac{m_z\xi + \sqrt{m_z^2 + (1-\xi^2) r^2}}{m_z^2 + r^2} (m_x, m_y, m_z) - (0, 0, \xi)`.

    Valid domain (exact): rays with :math:`\theta \le \theta_{max}`, where the radial map stops
    increasing; pixels with :math:`r \le r(\theta_{max})`, which equals the paper's
    :math:`r^2 \le 1/(2\alpha - 1)` for :math:`\alpha > 0.5`. The paper's projection test
    :math:`z > -w_2 d_1` is stricter and rejects valid rays just inside :math:`\theta_{max}`.
    Parameters: :math:`\xi \in [-1, 1]`, :math:`\alpha \in [0, 1]`.
    """

    name: ClassVar[str] = "double_sphere"
    param_names: ClassVar[tuple[str, ...]] = ("fx", "fy", "cx", "cy", "xi", "alpha")

    fx: float
    fy: float
    cx: float
    cy: float
    xi: float
    alpha: float
    width: int
    height: int

    def _check_model(self) -> None:
        if not -1.0 < self.xi <= 1.0:
            raise ValueError(f"DoubleSphere.xi: expected a value in (-1, 1] (at -1 the two "
                             f"spheres coincide and every ray maps to the centre), got {self.xi}")
        if not 0.0 <= self.alpha <= 1.0:
            raise ValueError(f"DoubleSphere.alpha: expected a value in [0, 1], got {self.alpha}")
        if self.alpha == 0.0 and self.xi < 0.0:
            raise ValueError(f"DoubleSphere.alpha: 0 with xi < 0 ({self.xi}) is no camera (a "
                             "unified model with negative xi); expected alpha > 0")

    def _d2(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        # 1 + 2 xi cos(t) + xi^2 as a sum of non-negative terms (no cancellation near 180 deg
        # at xi = 1): (1 - xi)^2 + 4 xi cos^2(t/2) for xi >= 0, (1 + xi)^2 + 4 |xi| sin^2(t/2)
        # otherwise.
        xi = self.xi
        if xi >= 0:
            return np.sqrt((1.0 - xi) ** 2 + 4.0 * xi * np.cos(theta / 2) ** 2)
        return np.sqrt((1.0 + xi) ** 2 - 4.0 * xi * np.sin(theta / 2) ** 2)

    def _xi_plus_cos(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """``xi + cos(t)`` as ``(xi - 1) + 2 cos^2(t/2)``: exact where it vanishes at xi = 1."""
        return (self.xi - 1.0) + 2.0 * np.cos(theta / 2) ** 2

    def _radius(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        a = self.alpha
        den = a * self._d2(theta) + (1 - a) * self._xi_plus_cos(theta)
        return np.sin(theta) / den

    def _radius_derivative(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        a, xi = self.alpha, self.xi
        s, c = np.sin(theta), np.cos(theta)
        d2 = self._d2(theta)
        den = a * d2 + (1 - a) * self._xi_plus_cos(theta)
        return (c * den + s * s * (a * xi / d2 + 1 - a)) / den**2

    def _lift(self, mx, my, r):  # noqa: D102 - closed form above
        a, xi = self.alpha, self.xi
        r2 = r * r
        mz = (1 - a * a * r2) / (a * np.sqrt(np.maximum(1 - (2 * a - 1) * r2, 0.0)) + 1 - a)
        k = (mz * xi + np.sqrt(np.maximum(mz * mz + (1 - xi * xi) * r2, 0.0))) / (mz * mz + r2)
        return np.stack([k * mx, k * my, k * mz - xi], axis=-1)
