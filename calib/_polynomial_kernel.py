"""Projection and unprojection kernels (numba) for models whose radial function is a polynomial
in the angle.

``r(theta) = sum_k c[k] theta**k`` (Kannala-Brandt, WoodScape's radial polynomial) has no closed
inverse; :func:`unproject_polynomial` does the whole unprojection of one pixel in one pass —
affine map, radius, domain test, the solve of ``r(theta) = r``, the ray — with no temporaries.

The solve (:func:`solve_theta`) is a safeguarded Newton iteration: it keeps a bracket
``[lo, hi]`` of the root and bisects whenever a Newton step would leave it, so it converges for
every radius in ``[0, r(theta_max)]``, including at the fold ``theta_max`` where ``r'`` vanishes.
It starts from a table of ``theta`` sampled uniformly in ``r`` (built with the same solve), which
puts it within ~1e-8 rad of the root, so two Newton steps and a confirming third are the usual cost.
"""

from __future__ import annotations

import math

import numba
import numpy as np

_MAX_ITERATIONS = 100


@numba.njit(cache=True, nogil=True, inline="always")
def _horner(c, x):
    acc = 0.0
    for k in range(c.shape[0] - 1, -1, -1):
        acc = acc * x + c[k]
    return acc


@numba.njit(cache=True, nogil=True)
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
        if abs(new - theta) <= 1e-15 * max(theta, 1.0):
            return new
        theta = new
    return theta


@numba.njit(cache=True, nogil=True)
def theta_table(c, dc, theta_max, r_max, n):
    """``theta`` at ``n`` radii spaced uniformly on ``[0, r_max]`` (the solve's start table)."""
    out = np.empty(n)
    step = r_max / (n - 1)
    for k in range(n):
        out[k] = solve_theta(k * step, k * step / dc[0] if dc[0] > 0 else 0.0, c, dc, theta_max)
    return out


@numba.njit(cache=True, nogil=True)
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
        theta = solve_theta(r, table[k] + w * (table[k + 1] - table[k]), c, dc, theta_max)
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


@numba.njit(cache=True, nogil=True)
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
