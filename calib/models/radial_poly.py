"""WoodScape's radial polynomial camera."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ..base import CameraModel
from ..registry import register


@register
@dataclass(frozen=True, kw_only=True)
class RadialPoly(CameraModel):
    r"""WoodScape ``radial_poly``: image radius in pixels as a polynomial of the angle.

    Projection: :math:`\rho(\theta) = k_1\theta + k_2\theta^2 + k_3\theta^3 + k_4\theta^4`
    (pixels), :math:`u = c_x + \rho\, x/\sqrt{x^2+y^2}`, :math:`v = c_y + a\,\rho\, y/\sqrt{x^2+y^2}`
    with the aspect ratio :math:`a`. The principal point is stored as WoodScape stores it, an
    offset from the image centre: :math:`c_x = W/2 + c_{x,off} - 0.5`,
    :math:`c_y = H/2 + c_{y,off} - 0.5` (WoodScape's ``projection.py``).

    Unprojection: safeguarded Newton solve of :math:`\rho(\theta) = \rho_d`.

    Valid domain: :math:`\theta \le \theta_{max}` where :math:`\rho'` first vanishes (or
    :math:`\pi`); requires :math:`k_1 > 0`.
    """

    name: ClassVar[str] = "radial_poly"
    param_names: ClassVar[tuple[str, ...]] = (
        "k1", "k2", "k3", "k4", "cx_offset", "cy_offset", "aspect_ratio",
    )

    k1: float
    k2: float = 0.0
    k3: float = 0.0
    k4: float = 0.0
    cx_offset: float = 0.0
    cy_offset: float = 0.0
    aspect_ratio: float = 1.0
    width: int
    height: int

    def _check_model(self) -> None:
        if self.k1 <= 0:
            raise ValueError(f"RadialPoly.k1: expected > 0 (pixels per radian), got {self.k1}")
        if self.aspect_ratio <= 0:
            raise ValueError(f"RadialPoly.aspect_ratio: expected > 0, got {self.aspect_ratio}")

    def _affine(self) -> tuple[float, float, float, float]:
        return (
            1.0,
            self.aspect_ratio,
            self.width / 2 + self.cx_offset - 0.5,
            self.height / 2 + self.cy_offset - 0.5,
        )

    def _radius_coefficients(self) -> tuple[float, ...]:
        return (0.0, self.k1, self.k2, self.k3, self.k4)
