"""Projection and unprojection kernels (numba) for models whose radial function is a polynomial
in the angle.

``r(theta) = sum_k c[k] theta**k`` (Kannala-Brandt, WoodScape's radial polynomial) has no closed
inverse; :func:`unproject_polynomial` does the whole unprojection of one pixel in one pass —
affine map, radius, domain test, the solve of ``r(theta) = r``, the ray — with no temporaries.

The solve (:func:`solve_theta`) is a safeguarded Newton iteration: it keeps a bracket
``[lo, hi]`` of the root and bisects whenever a Newton step would leave it, so it converges for
every radius in ``[0, r(theta_max)]``, including at the fold ``theta_max`` where ``r'`` vanishes.
It starts from a cubic Hermite interpolation of ``theta(r)`` tabulated uniformly in ``r`` (built
with the same solve), within ~1e-13 rad of the root, so that one Newton step is the usual cost.
"""

from __future__ import annotations

import math

import numba
import numpy as np

_MAX_ITERATIONS = 100

# Accept a Newton step this small without a confirming iteration where r' is not small: the error
# left is about |r''/(2 r')| step**2, far below rounding there.
_QUICK_STEP = 1e-10
_QUICK_SLOPE = 1e-3
# Coefficients travel as tuples of floats (values: no reference counting in per-pixel calls).
_JIT = dict(cache=True, nogil=True, error_model="numpy")


@numba.njit(**_JIT)
def _horner(c, x):
    acc = 0.0
    for k in range(len(c) - 1, -1, -1):
        acc = acc * x + c[k]
    return acc


@numba.njit(**_JIT)
def solve_theta(r, start, c, dc, theta_max):
    """The ``theta`` in ``[0, theta_max]`` with ``r(theta) = r`` (``0 <= r <= r(theta_max)``)."""
    lo = 0.0
    hi = theta_max
    theta = min(max(start, lo), hi)
    for _ in range(_MAX_ITERATIONS):
        f = _horner(c, theta) - r
        if f <= 0.0:
            lo = theta
        else:
            hi = theta
        d = _horner(dc, theta)
        new = theta - f / d if d > 0.0 else -1.0
        if not (lo <= new <= hi):
            new = 0.5 * (lo + hi)
        elif abs(new - theta) <= _QUICK_STEP * max(theta, 1.0) and d >= _QUICK_SLOPE * dc[0]:
            return new
        if abs(new - theta) <= 1e-15 * max(theta, 1.0):
            return new
        theta = new
    return theta


@numba.njit(**_JIT)
def theta_table(c, dc, theta_max, r_max, n):
    """The solve's start table: ``theta`` at ``n`` radii spaced uniformly on ``[0, r_max]`` and
    ``h dtheta/dr`` there (``h`` the spacing; ``inf`` at the fold), shape (n, 2), for cubic
    Hermite interpolation."""
    out = np.empty((n, 2))
    step = r_max / (n - 1)
    for k in range(n):
        theta = solve_theta(k * step, k * step / dc[0] if dc[0] > 0 else 0.0, c, dc, theta_max)
        d = _horner(dc, theta)
        out[k, 0] = theta
        out[k, 1] = step / d if d > 0.0 else np.inf
    return out


@numba.njit(**_JIT)
def unproject_polynomial(pixels, fx, fy, cx, cy, c, dc, theta_max, r_max, table, rays, valid):
    """Fill ``rays`` (N, 3) and ``valid`` (N,) for ``pixels`` (N, 2); NaN rays where invalid."""
    nan = np.nan
    scale_table = (table.shape[0] - 1) / r_max
    last = table.shape[0] - 2
    for i in range(pixels.shape[0]):
        mx = (pixels[i, 0] - cx) / fx
        my = (pixels[i, 1] - cy) / fy
        r = math.sqrt(mx * mx + my * my)
        if not r <= r_max:  # also catches NaN
            rays[i, 0] = nan
            rays[i, 1] = nan
            rays[i, 2] = nan
            valid[i] = False
            continue
        x = r * scale_table
        k = min(int(x), last)
        w = x - k
        t0, m0, t1, m1 = table[k, 0], table[k, 1], table[k + 1, 0], table[k + 1, 1]
        if m1 < np.inf:  # cubic Hermite: within ~1e-13 rad, so one Newton step is exact
            w1 = 1.0 - w
            start = (w1 * w1 * ((1.0 + 2.0 * w) * t0 + w * m0)
                     + w * w * ((3.0 - 2.0 * w) * t1 - w1 * m1))
        else:  # the interval ending at the fold
            start = t0 + w * (t1 - t0)
        theta = solve_theta(r, start, c, dc, theta_max)
        s = math.sin(theta)
        z = math.cos(theta)
        scale = s / r if r > 0.0 else 0.0
        rx = scale * mx
        ry = scale * my
        norm = math.sqrt(rx * rx + ry * ry + z * z)
        rays[i, 0] = rx / norm
        rays[i, 1] = ry / norm
        rays[i, 2] = z / norm
        valid[i] = True


@numba.njit(**_JIT)
def project_polynomial(rays, fx, fy, cx, cy, c, theta_max, pixels, valid):
    """Fill ``pixels`` (N, 2) and ``valid`` (N,) for ``rays`` (N, 3); NaN pixels where invalid
    (non-finite or zero rays, rays beyond ``theta_max``)."""
    nan = np.nan
    for i in range(rays.shape[0]):
        x, y, z = rays[i, 0], rays[i, 1], rays[i, 2]
        rho = math.sqrt(x * x + y * y)
        theta = math.atan2(rho, z)
        ok = (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)
              and (rho > 0.0 or z > 0.0) and theta <= theta_max)
        if ok:
            scale = _horner(c, theta) / rho if rho > 0.0 else 0.0
            u = fx * scale * x + cx
            v = fy * scale * y + cy
            ok = math.isfinite(u) and math.isfinite(v)
        if ok:
            pixels[i, 0] = u
            pixels[i, 1] = v
        else:
            pixels[i, 0] = nan
            pixels[i, 1] = nan
        valid[i] = ok
