"""Projection and unprojection kernels (numba) for models whose radial function is a polynomial
in the angle.

``r(theta) = sum_k c[k] theta**k`` (Kannala-Brandt, WoodScape's radial polynomial) has no closed
inverse; :func:`unproject_polynomial` does the whole unprojection of one pixel in one pass —
affine map, radius, domain test, the solve of ``r(theta) = r``, the ray — with no temporaries.

The solve (:func:`solve_theta`) is a safeguarded Newton iteration: it keeps a bracket
``[lo, hi]`` of the root and bisects whenever a Newton step would leave it, so it converges for
every radius in ``[0, r(theta_max)]``, including at the fold ``theta_max`` where ``r'`` vanishes.
A cubic Hermite interpolation of ``theta(r)`` tabulated uniformly in ``r`` (built with the same
solve, 16385 samples) is within rounding of the root on every interval where it was checked to be
(quarter points against the solve, :data:`EXACT`), so there the unprojection needs no solve; on the
other intervals (near the fold, where ``r'`` vanishes) it is the solve's start.
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
# An interpolation interval needs no solve when the cubic is this close to the root (relative to
# max(theta, 1)): the rounding of the solve itself.
EXACT = 5e-16
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
def _hermite(table, k, w):
    """Cubic Hermite interpolation of ``theta`` at ``w`` in [0, 1] of interval ``k``."""
    t0, m0, t1, m1 = table[k, 0], table[k, 1], table[k + 1, 0], table[k + 1, 1]
    if not m1 < np.inf:  # the interval ending at the fold: linear
        return t0 + w * (t1 - t0)
    w1 = 1.0 - w
    return w1 * w1 * ((1.0 + 2.0 * w) * t0 + w * m0) + w * w * ((3.0 - 2.0 * w) * t1 - w1 * m1)


@numba.njit(**_JIT)
def theta_table(c, dc, theta_max, r_max, n):
    """The inverse's table: ``theta`` at ``n`` radii spaced uniformly on ``[0, r_max]``,
    ``h dtheta/dr`` there (``h`` the spacing; ``inf`` at the fold) for cubic Hermite
    interpolation, and whether that interpolation is exact on the interval that starts there
    (1.0: within ``EXACT`` of the solve at its quarter points, so no solve is needed), shape
    (n, 3)."""
    out = np.empty((n, 3))
    step = r_max / (n - 1)
    for k in range(n):
        theta = solve_theta(k * step, k * step / dc[0] if dc[0] > 0 else 0.0, c, dc, theta_max)
        d = _horner(dc, theta)
        out[k, 0] = theta
        out[k, 1] = step / d if d > 0.0 else np.inf
        out[k, 2] = 0.0
    for k in range(n - 1):
        exact = 1.0
        for w in (0.25, 0.5, 0.75):
            guess = _hermite(out, k, w)
            truth = solve_theta((k + w) * step, guess, c, dc, theta_max)
            if not abs(guess - truth) <= EXACT * max(truth, 1.0):
                exact = 0.0
        out[k, 2] = exact
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
        theta = _hermite(table, k, x - k)
        if table[k, 2] == 0.0:  # not exact here (near the fold): solve from it
            theta = solve_theta(r, theta, c, dc, theta_max)
        s = math.sin(theta)
        z = math.cos(theta)
        scale = s / r if r > 0.0 else 0.0
        rays[i, 0] = scale * mx  # unit: sin^2 + cos^2 = 1 to rounding
        rays[i, 1] = scale * my
        rays[i, 2] = z
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
