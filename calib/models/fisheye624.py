"""Project Aria's FISHEYE624: Kannala-Brandt radial polynomial to theta^13, tangential and
thin-prism terms, one focal length."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_points
from ..base import CameraModel, kernels
from ..registry import register

#: Newton iterations of the tangential/thin-prism inversion, and the residual (normalised units,
#: about 1e-7 px at f = 300) below which a pixel counts as inverted.
_NEWTON_STEPS = 20
_INVERSE_TOLERANCE = 1e-12
#: The pixel map of normalised coordinates: the radial kernels run before the non-radial stage.
_NORMALISED = (1.0, 1.0, 0.0, 0.0)


@register
@dataclass(frozen=True, kw_only=True)
class Fisheye624(CameraModel):
    r"""Project Aria's ``FISHEYE624`` ("FisheyeRadTanThinPrism"), 15 parameters
    ``f, cx, cy, k0..k5, p0, p1, s0..s3``.

    Projection of a ray :math:`(x, y, z)`: :math:`\theta = \operatorname{atan2}(\rho, z)`,
    :math:`\rho = \sqrt{x^2 + y^2}`;

    - radial: :math:`\theta_d = \theta + k_0\theta^3 + k_1\theta^5 + \dots + k_5\theta^{13}`,
      :math:`(a, b) = \theta_d\,(x, y) / \rho`;
    - tangential (:math:`r^2 = a^2 + b^2`): :math:`a \mathrel{+}= p_0 (r^2 + 2a^2) + 2 p_1 a b`,
      :math:`b \mathrel{+}= p_1 (r^2 + 2b^2) + 2 p_0 a b`;
    - thin prism: :math:`a \mathrel{+}= s_0 r^2 + s_1 r^4`, :math:`b \mathrel{+}= s_2 r^2 + s_3 r^4`;
    - :math:`u = f a + c_x`, :math:`v = f b + c_y`.

    Unprojection: Newton's method on the tangential and thin-prism map (2x2 Jacobian, started at
    the distorted point), then the radial polynomial's safeguarded solve (the polynomial models'
    kernel). A pixel whose inversion does not reproject within :data:`_INVERSE_TOLERANCE` is not
    valid.

    Valid domain: the radial part's :math:`\theta \le \theta_{max}` (first stationary point of
    :math:`\theta_d`, or :math:`\pi`) and, when ``valid_radius`` is set (Aria's calibration
    gives one, in pixels from the principal point), pixels within it. The tangential and
    thin-prism terms of real calibrations are 1e-3 or smaller: they keep the map one-to-one over
    the image.
    """

    name: ClassVar[str] = "fisheye624"
    radially_symmetric: ClassVar[bool] = False
    param_names: ClassVar[tuple[str, ...]] = (
        "f", "cx", "cy", "k0", "k1", "k2", "k3", "k4", "k5", "p0", "p1", "s0", "s1", "s2", "s3",
        "valid_radius")

    f: float
    cx: float
    cy: float
    k0: float = 0.0
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    k4: float = 0.0
    k5: float = 0.0
    p0: float = 0.0
    p1: float = 0.0
    s0: float = 0.0
    s1: float = 0.0
    s2: float = 0.0
    s3: float = 0.0
    valid_radius: float = 0.0
    width: int
    height: int

    def _affine(self) -> tuple[float, float, float, float]:
        return self.f, self.f, self.cx, self.cy

    def _check_model(self) -> None:
        if self.valid_radius < 0:
            raise ValueError(f"Fisheye624.valid_radius: expected pixels >= 0 (0: no limit), "
                             f"got {self.valid_radius}")
        for name in ("k0", "k1", "k2", "k3", "k4", "k5"):
            if abs(getattr(self, name)) > 1e3:
                raise ValueError(f"Fisheye624.{name}: expected |{name}| <= 1000, got "
                                 f"{getattr(self, name)}")
        for name in ("p0", "p1", "s0", "s1", "s2", "s3"):
            if abs(getattr(self, name)) > 0.1:
                raise ValueError(f"Fisheye624.{name}: expected |{name}| <= 0.1 (a small "
                                 f"tangential or thin-prism term), got {getattr(self, name)}")

    def _radius_coefficients(self) -> tuple[float, ...]:
        k = (self.k0, self.k1, self.k2, self.k3, self.k4, self.k5)
        c = [0.0, 1.0]
        for ki in k:
            c += [0.0, ki]
        return tuple(c)

    # ---- the non-radial stage, in normalised units -------------------------------------------
    def _distort(self, a: NDArray, b: NDArray) -> tuple[NDArray, NDArray]:
        r2 = a * a + b * b
        r4 = r2 * r2
        da = self.p0 * (r2 + 2 * a * a) + 2 * self.p1 * a * b + self.s0 * r2 + self.s1 * r4
        db = self.p1 * (r2 + 2 * b * b) + 2 * self.p0 * a * b + self.s2 * r2 + self.s3 * r4
        return a + da, b + db

    def _distort_jacobian(self, a: NDArray, b: NDArray) -> tuple[NDArray, ...]:
        r2 = a * a + b * b
        p0, p1, s0, s1, s2, s3 = self.p0, self.p1, self.s0, self.s1, self.s2, self.s3
        # d(r2)/da = 2a, d(r4)/da = 4 a r2
        j00 = 1 + p0 * 6 * a + 2 * p1 * b + s0 * 2 * a + s1 * 4 * a * r2
        j01 = p0 * 2 * b + 2 * p1 * a + s0 * 2 * b + s1 * 4 * b * r2
        j10 = p1 * 2 * a + 2 * p0 * b + s2 * 2 * a + s3 * 4 * a * r2
        j11 = 1 + p1 * 6 * b + 2 * p0 * a + s2 * 2 * b + s3 * 4 * b * r2
        return j00, j01, j10, j11

    def _undistort(self, ad: NDArray, bd: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        a, b = ad.copy(), bd.copy()
        with np.errstate(all="ignore"):
            for _ in range(_NEWTON_STEPS):
                fa, fb = self._distort(a, b)
                ea, eb = fa - ad, fb - bd
                j00, j01, j10, j11 = self._distort_jacobian(a, b)
                det = j00 * j11 - j01 * j10
                a = a - (j11 * ea - j01 * eb) / det
                b = b - (-j10 * ea + j00 * eb) / det
            fa, fb = self._distort(a, b)
            ok = np.hypot(fa - ad, fb - bd) <= _INVERSE_TOLERANCE * np.maximum(1.0, np.hypot(ad, bd))
        return a, b, ok

    @cached_property
    def _has_tangential(self) -> bool:
        return any(getattr(self, n) != 0.0 for n in ("p0", "p1", "s0", "s1", "s2", "s3"))

    def _inside_radius(self, pixels: NDArray) -> NDArray[np.bool_]:
        if self.valid_radius <= 0:
            return np.ones(pixels.shape[:-1], dtype=bool)
        with np.errstate(invalid="ignore"):
            return np.hypot(pixels[..., 0] - self.cx, pixels[..., 1] - self.cy) <= self.valid_radius

    # ---- the interface ----------------------------------------------------------------------
    def project(self, rays: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        p = as_points(rays, 3, "rays")
        c, _ = self._polynomial_tuples
        norm, valid = self._run_kernel(kernels().project_polynomial, p, 2, c,
                                       self.theta_max, affine=_NORMALISED)
        with np.errstate(all="ignore"):
            a, b = self._distort(norm[..., 0], norm[..., 1])
            pixels = np.stack([self.f * a + self.cx, self.f * b + self.cy], axis=-1)
        valid &= np.isfinite(pixels).all(axis=-1) & self._inside_radius(pixels)
        pixels[~valid] = np.nan
        return pixels, valid

    def unproject(self, pixels: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        q = as_points(pixels, 2, "pixels")
        ad = (q[..., 0] - self.cx) / self.f
        bd = (q[..., 1] - self.cy) / self.f
        if self._has_tangential:
            a, b, ok = self._undistort(ad, bd)
        else:
            a, b, ok = ad, bd, np.isfinite(ad) & np.isfinite(bd)
        norm = np.stack([np.where(ok, a, np.nan), np.where(ok, b, np.nan)], axis=-1)
        c, dc = self._polynomial_tuples
        rays, valid = self._run_kernel(kernels().unproject_polynomial, norm, 3, c, dc,
                                       self.theta_max, self.radius_max, self._theta_table,
                                       affine=_NORMALISED)
        valid &= ok & self._inside_radius(q)
        rays[~valid] = np.nan
        return rays, valid

    def project_jacobian(self, rays: ArrayLike):
        """Pixels and ``d(u, v) / d(x, y, z)``, by central differences of :meth:`project`
        (relative step 1e-6: about 1e-8 relative error)."""
        p = as_points(rays, 3, "rays")
        pixels, valid = self.project(p)
        jac = np.empty(p.shape[:-1] + (2, 3))
        scale = np.linalg.norm(p, axis=-1)
        for i in range(3):
            h = 1e-6 * np.where(scale > 0, scale, 1.0)
            step = np.zeros_like(p)
            step[..., i] = h
            hi, ok_hi = self.project(p + step)
            lo, ok_lo = self.project(p - step)
            jac[..., :, i] = (hi - lo) / (2 * h[..., None])
            valid &= ok_hi & ok_lo
        jac[~valid] = np.nan
        pixels[~valid] = np.nan
        return pixels, jac, valid
