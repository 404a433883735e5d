"""The one interface every camera model implements.

All models here are *central* and *radially symmetric* about the optical axis after the affine
pixel map ``u = fx * mx + cx, v = fy * my + cy``. A model is therefore fully described by its
radial function ``r(theta)``: the distance from the principal point, in normalised units, at which a
ray at angle ``theta`` off the optical axis lands. This base class turns that one function (and
its derivative) into projection, unprojection (g(u) of the paper), Jacobians and validity masks,
so that a new model only has to state its formula.

Valid domain, for every model
-----------------------------
``theta_max`` is the first angle in ``(0, pi]`` where ``r(theta)`` stops increasing (or stops
being finite and positive); ``pi`` if it never does. Only on ``[0, theta_max]`` is the map from
ray to pixel one-to-one, so:

- ``project`` is valid for rays with ``theta <= theta_max``;
- ``unproject`` is valid for pixels with normalised radius ``r <= r_max = r(theta_max)``.

Every pixel reported valid unprojects to the one ray that projects back onto it.

How to add a model (four steps)
-------------------------------
1. Create ``calib/models/<name>.py`` with a frozen, keyword-only dataclass deriving from
   :class:`CameraModel`; fields: intrinsics in canonical order, then ``width`` and ``height``.
2. State the formula and its valid domain in the class docstring, then give the radial
   function: either ``_radius_coefficients()`` when ``r(theta)`` is a polynomial in ``theta``
   (projection, the derivative and a fused numba unprojection follow), or ``_radius(theta)``,
   ``_radius_derivative(theta)`` and a closed-form inverse ``_lift``. Override ``_check_model``
   for parameter ranges.
3. Decorate the class with ``@register`` (``calib/registry.py``) under its canonical ``name``.
4. Add it to ``tests/test_camera_models.py::MODEL_SAMPLES``; the generic round-trip and Jacobian
   tests then run on it. Add reader/writer support in ``calib/readers`` if a file format names it.
"""

from __future__ import annotations

import dataclasses
import math
from functools import cached_property
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._arrays import as_points, check_real, check_size

_GRID_SAMPLES = 8192

#: Pixels: no camera has a longer focal length (1e300 would make every product overflow).
MAX_FOCAL = 1e7
#: Normalised radius beyond which a projection is not valid (a ray at the edge of a model's
#: domain where r(theta) -> infinity, e.g. 90 degrees for a pinhole or a unified xi = 0).
MAX_RADIUS = 1e6
_TABLE_SAMPLES = 16385


def kernels():
    """The numba kernels (``calib/_polynomial_kernel.py``), imported on first use: numba takes a
    tenth of a second to import, which ``import fisheyemotion`` does not pay."""
    from . import _polynomial_kernel

    return _polynomial_kernel


def pixel_grid(width: int, height: int) -> NDArray[np.float64]:
    """Return the ``(height, width, 2)`` array of pixel centres ``(u, v)`` (OpenCV convention)."""
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    return np.stack([u, v], axis=-1)


class CameraModel:
    """Base of every camera model: batch projection and unprojection over any leading shape.

    Subclasses are frozen keyword-only dataclasses. Angles are radians, pixels follow OpenCV
    (``(0, 0)`` is the centre of the top-left pixel), the camera frame is x right, y down,
    z forward.
    """

    name: ClassVar[str] = ""
    #: False for models with terms that are not radial (tangential, thin prism): their pixel
    #: domain is not a disk of ``radius_max``, only their radial part's is.
    radially_symmetric: ClassVar[bool] = True
    #: Intrinsic parameter names in canonical order (what ``params`` returns).
    param_names: ClassVar[tuple[str, ...]] = ()

    # ---- subclass hooks -------------------------------------------------------------------
    def _radius_coefficients(self) -> tuple[float, ...] | None:
        """``(c0, c1, ...)`` when ``r(theta) = sum_k c_k theta**k``; ``None`` otherwise.

        A polynomial model needs nothing else: ``_radius``, ``_radius_derivative`` and the
        unprojection (a fused numba solve, ``calib/_polynomial_kernel.py``) follow from it.
        """
        return None

    def _radius(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """Normalised radius ``r(theta)``."""
        c, _ = self._polynomial
        return np.polynomial.polynomial.polyval(theta, c)

    def _radius_derivative(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """``dr/dtheta``."""
        _, dc = self._polynomial
        return np.polynomial.polynomial.polyval(theta, dc)

    def _check_model(self) -> None:
        """Raise ValueError naming the parameter when a model-specific range is violated."""

    def _affine(self) -> tuple[float, float, float, float]:
        """``(fx, fy, cx, cy)`` of the pixel map; overridden where the file stores others."""
        return self.fx, self.fy, self.cx, self.cy  # type: ignore[attr-defined]

    def _lift(
        self, mx: NDArray[np.float64], my: NDArray[np.float64], r: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Rays (any positive length) for normalised points with radius ``r <= r_max``.

        Closed-form models override this; polynomial models never reach it.
        """
        raise NotImplementedError(
            f"{type(self).__name__}: give _radius_coefficients or a closed-form _lift"
        )

    # ---- construction ----------------------------------------------------------------------
    def __post_init__(self) -> None:
        owner = type(self).__name__
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            if f.name in ("width", "height"):
                object.__setattr__(self, f.name, check_size(f.name, value, owner=owner))
            else:
                object.__setattr__(self, f.name, check_real(f.name, value, owner=owner))
        fx, fy, _, _ = self._affine()
        for label, value in (("fx", fx), ("fy", fy)):
            if not 0 < value <= MAX_FOCAL:
                raise ValueError(f"{owner}.{label}: expected a focal length in (0, {MAX_FOCAL:g}] "
                                 f"pixels, got {value}")
        self._check_model()

    @property
    def params(self) -> dict[str, float]:
        """Intrinsics by name, in canonical order (without ``width``/``height``)."""
        return {n: getattr(self, n) for n in self.param_names}

    def to_dict(self) -> dict[str, Any]:
        """``{"model": name, **params, "width": ..., "height": ...}``."""
        return {"model": self.name, **self.params, "width": self.width, "height": self.height}  # type: ignore[attr-defined]

    # ---- domain ----------------------------------------------------------------------------
    @cached_property
    def theta_max(self) -> float:
        """Largest off-axis angle (radians) of the one-to-one domain, in ``(0, pi]``."""
        theta = np.linspace(0.0, math.pi, _GRID_SAMPLES + 1)[1:]
        ok = self._monotone(theta)
        if ok.all():
            return math.pi
        first_bad = int(np.argmin(ok))
        lo = float(theta[first_bad - 1]) if first_bad > 0 else 0.0
        hi = float(theta[first_bad])
        for _ in range(200):  # bisection to machine precision
            mid = 0.5 * (lo + hi)
            if mid in (lo, hi):
                break
            if self._monotone(np.array([mid]))[0]:
                lo = mid
            else:
                hi = mid
        return lo

    def _monotone(self, theta: NDArray[np.float64]) -> NDArray[np.bool_]:
        with np.errstate(all="ignore"):
            r = self._radius(theta)
            dr = self._radius_derivative(theta)
        return np.isfinite(r) & (r > 0) & np.isfinite(dr) & (dr > 0)

    @cached_property
    def radius_max(self) -> float:
        """Normalised radius ``r(theta_max)``: the edge of the unprojection domain."""
        with np.errstate(all="ignore"):
            r = float(self._radius(np.array([self.theta_max]))[0])
        return r if math.isfinite(r) else math.inf

    # ---- projection ------------------------------------------------------------------------
    def project(self, rays: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Project rays (any non-zero length) to pixels.

        Parameters
        ----------
        rays : array_like, shape (..., 3)
            Directions in the camera frame.

        Returns
        -------
        pixels : ndarray, shape (..., 2)
            ``(u, v)``; NaN where invalid.
        valid : ndarray of bool, shape (...)
            False for zero or non-finite rays and rays beyond ``theta_max``.
        """
        p = as_points(rays, 3, "rays")
        if self._radius_coefficients() is not None:
            return self._project_polynomial(p)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        rho = np.hypot(x, y)
        theta = np.arctan2(rho, z)
        valid = np.isfinite(p).all(axis=-1) & ((rho > 0) | (z > 0)) & (theta <= self.theta_max)
        fx, fy, cx, cy = self._affine()
        with np.errstate(all="ignore"):
            r = self._radius(theta)
            scale = np.where(rho > 0, r / np.where(rho > 0, rho, 1.0), 0.0)
            pixels = np.stack([fx * scale * x + cx, fy * scale * y + cy], axis=-1)
        valid &= np.isfinite(pixels).all(axis=-1) & (r < MAX_RADIUS)
        pixels[~valid] = np.nan
        return pixels, valid

    def unproject(self, pixels: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """g(u): pixels to unit rays on the sphere.

        Parameters
        ----------
        pixels : array_like, shape (..., 2)
            ``(u, v)`` in OpenCV's convention.

        Returns
        -------
        rays : ndarray, shape (..., 3)
            Unit-norm float64 rays; NaN where invalid.
        valid : ndarray of bool, shape (...)
            False for non-finite pixels and pixels beyond the model's domain ``r > r_max``.
        """
        q = as_points(pixels, 2, "pixels")
        if self._radius_coefficients() is not None:
            return self._unproject_polynomial(q)
        fx, fy, cx, cy = self._affine()
        mx = (q[..., 0] - cx) / fx
        my = (q[..., 1] - cy) / fy
        r = np.hypot(mx, my)
        valid = np.isfinite(r) & (r <= self.radius_max)
        r_in = np.where(valid, r, 0.0)
        with np.errstate(all="ignore"):
            rays = self._lift(np.where(valid, mx, 0.0), np.where(valid, my, 0.0), r_in)
            rays = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
        valid &= np.isfinite(rays).all(axis=-1)
        rays[~valid] = np.nan
        return rays, valid

    def project_jacobian(
        self, rays: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """Pixels and the Jacobian ``d(u, v) / d(x, y, z)`` of :meth:`project`.

        Returns
        -------
        pixels : ndarray, shape (..., 2)
        jacobian : ndarray, shape (..., 2, 3)
            NaN where invalid.
        valid : ndarray of bool, shape (...)
        """
        p = as_points(rays, 3, "rays")
        pixels, valid = self.project(p)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        rho = np.hypot(x, y)
        n2 = x * x + y * y + z * z
        theta = np.arctan2(rho, z)
        on_axis = rho == 0
        rho_s = np.where(on_axis, 1.0, rho)
        with np.errstate(all="ignore"):
            r = self._radius(theta)
            dr = self._radius_derivative(theta)
            # m = s * (x, y) with s = r(theta) / rho; on the axis s -> r'(0) / z.
            dr0 = self._radius_derivative(np.zeros(1))[0]
            s = np.where(on_axis, dr0 / z, r / rho_s)
            q = np.where(on_axis, 0.0, (dr * z / n2 - r / rho_s) / rho_s**2)
            ds_dz = np.where(on_axis, -dr0 / z**2, -dr / n2)
        fx, fy, _, _ = self._affine()
        jac = np.empty(p.shape[:-1] + (2, 3))
        jac[..., 0, 0] = fx * (s + x * x * q)
        jac[..., 0, 1] = fx * x * y * q
        jac[..., 0, 2] = fx * x * ds_dz
        jac[..., 1, 0] = fy * x * y * q
        jac[..., 1, 1] = fy * (s + y * y * q)
        jac[..., 1, 2] = fy * y * ds_dz
        jac[~valid] = np.nan
        return pixels, jac, valid

    # ---- polynomial models ------------------------------------------------------------------
    @cached_property
    def _polynomial(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        coeffs = self._radius_coefficients()
        if coeffs is None:
            raise NotImplementedError(
                f"{type(self).__name__}: give _radius_coefficients or _radius/_radius_derivative"
            )
        c = np.asarray(coeffs, dtype=np.float64)
        return c, np.polynomial.polynomial.polyder(c) if len(c) > 1 else np.zeros(1)

    @cached_property
    def _polynomial_tuples(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        c, dc = self._polynomial
        return tuple(map(float, c)), tuple(map(float, dc))

    @cached_property
    def _theta_table(self) -> NDArray[np.float64]:
        c, dc = self._polynomial_tuples
        return kernels().theta_table(c, dc, self.theta_max, self.radius_max, _TABLE_SAMPLES)

    def _project_polynomial(
        self, p: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        c, _ = self._polynomial_tuples
        return self._run_kernel(kernels().project_polynomial, p, 2, c, self.theta_max)

    def _unproject_polynomial(
        self, q: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        c, dc = self._polynomial_tuples
        return self._run_kernel(kernels().unproject_polynomial, q, 3, c, dc,
                                self.theta_max, self.radius_max, self._theta_table)

    def _run_kernel(self, kernel, points: NDArray[np.float64], out_dim: int, *args,
                    affine: tuple[float, float, float, float] | None = None
                    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """``kernel(points (N, d), fx, fy, cx, cy, *args, out (N, out_dim), valid (N,))`` over
        any leading shape of ``points``; ``affine`` replaces the model's pixel map (``(1, 1, 0,
        0)``: normalised coordinates)."""
        flat = np.ascontiguousarray(points.reshape(-1, points.shape[-1]))
        out = np.empty((len(flat), out_dim))
        valid = np.empty(len(flat), dtype=bool)
        kernel(flat, *(self._affine() if affine is None else affine), *args, out, valid)
        lead = points.shape[:-1]
        return out.reshape(lead + (out_dim,)), valid.reshape(lead)

    # ---- image-level helpers ---------------------------------------------------------------
    @cached_property
    def _pixel_rays(self) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        return self.unproject(pixel_grid(self.width, self.height))  # type: ignore[attr-defined]

    def pixel_rays(self) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Rays of every pixel centre, ``(H, W, 3)``, and their validity ``(H, W)`` (cached)."""
        rays, valid = self._pixel_rays
        return rays.copy(), valid.copy()

    def valid_pixel_mask(self) -> NDArray[np.bool_]:
        """``(H, W)`` bool: pixels that have a ray (inside the model's domain)."""
        return self._pixel_rays[1].copy()

    @cached_property
    def fov_deg(self) -> float:
        """Field of view in degrees: twice the largest off-axis angle of any valid pixel."""
        rays, valid = self._pixel_rays
        if not valid.any():
            return 0.0
        z = np.clip(rays[valid][:, 2], -1.0, 1.0)
        return float(np.degrees(2.0 * np.arccos(z.min())))
