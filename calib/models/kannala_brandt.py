"""Kannala-Brandt (equidistant polynomial) camera."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ..base import CameraModel
from ..registry import register

#: Largest |k_i| accepted: real fisheye calibrations stay below 3; 1e300 would overflow.
MAX_COEFFICIENT = 1e3


@register
@dataclass(frozen=True, kw_only=True)
class KannalaBrandt(CameraModel):
    r"""Kannala-Brandt model with four coefficients.

    Known as OpenCV ``cv2.fisheye``, Basalt ``kb4``, Kalibr ``pinhole`` + ``equidistant`` and COLMAP
    ``OPENCV_FISHEYE``.

    Projection: :math:`\theta = \operatorname{atan2}(\sqrt{x^2+y^2}, z)` (the whole sphere, not
    ``atan(r/z)``), :math:`d(\theta) = \theta (1 + k_1\theta^2 + k_2\theta^4 + k_3\theta^6 +
    k_4\theta^8)`, :math:`u = f_x d(\theta)\, x/\sqrt{x^2+y^2} + c_x` (same for v).

    Unprojection: safeguarded Newton solve of :math:`d(\theta) = r_d` on
    :math:`[0, \theta_{max}]` (the polynomial models' numba kernel).

    Valid domain: :math:`\theta \le \theta_{max}`, the first angle where :math:`d'(\theta) = 0`
    (or :math:`\pi`); pixels with :math:`r_d \le d(\theta_{max})`.
    """

    name: ClassVar[str] = "kannala_brandt"
    param_names: ClassVar[tuple[str, ...]] = ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")

    fx: float
    fy: float
    cx: float
    cy: float
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    k4: float = 0.0
    width: int
    height: int

    def _check_model(self) -> None:
        for name in ("k1", "k2", "k3", "k4"):
            if abs(getattr(self, name)) > MAX_COEFFICIENT:
                raise ValueError(f"KannalaBrandt.{name}: expected |{name}| <= {MAX_COEFFICIENT} "
                                 f"(real lenses: below 3), got {getattr(self, name)}")

    def _radius_coefficients(self) -> tuple[float, ...]:
        return (0.0, 1.0, 0.0, self.k1, 0.0, self.k2, 0.0, self.k3, 0.0, self.k4)
