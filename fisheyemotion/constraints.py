"""The spherical constraint engine (Mariotti & Hughes, ITSC 2019), derived on the epipolar circle.

See ``docs/geometry.md`` for the derivation. In short, with ``C`` and ``C'`` the previous and
current camera centres, ``b = |C - C'|``, ``e' = (C - C') / b`` and a static point
``X = C + lambda p``::

    X - C' = b e' + lambda p,      lambda > 0

so the current ray ``p'`` of a static point is a *positive* combination of ``e'`` and ``p``: it lies
on the great-circle arc from ``e'`` (``lambda -> 0``) to ``p`` (``lambda -> infinity``). With angular
coordinates on that circle (``e'`` at 0, ``p`` at ``Theta = angle(e', p)``), everything the paper
tests is an ordering of angles:

- epipolar:      ``xi_e = |n' . p'|``, the sine of the distance of ``p'`` from the circle;
- positive depth: ``p'_Pi`` (``p'`` projected on the plane) beyond ``p`` (``phi > Theta``):
  ``xi_d = |p'_Pi x p|``; optionally also beyond ``e'`` (``phi < 0``): ``xi_d = |p'_Pi x e'|``;
- the road point ``P = C + delta p``, ``delta = eta / (p . h)``, is seen from ``C'`` at
  ``phi_r in (0, Theta)``; ``p'_Pi`` between ``phi_r`` and ``Theta`` triangulates *below* the road
  (``xi_h``), between ``0`` and ``phi_r`` *above* it (``xi_p``); both are ``|p'_Pi x p'_r|`` minus a
  dead band, clamped at 0, and apply only below the horizon.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .calib._arrays import as_points
from .calib.transforms import check_rigid
from .params import Params
from .road import Road

#: A projected current ray shorter than this has no direction on the epipolar plane.
_DEGENERATE = 1e-12


@dataclass(frozen=True, eq=False)
class ConstraintResult:
    """Per-ray deviations; every array has the leading shape of the input rays.

    Attributes
    ----------
    epipolar, depth, height, antiparallel : ndarray of float64, shape (...)
        ``xi_e, xi_d, xi_h, xi_p`` in ``[0, 1]``; 0 for the four when the camera stands still.
    likelihood : ndarray of float64, shape (...)
        Weighted mean of the four, or ``|p' x p|`` when the camera stands still.
    valid : ndarray of bool, shape (...)
        False (and NaN everywhere) for non-finite rays and rays within ``epipole_margin`` of the
        epipole ``e'``.
    static_camera : bool
        The baseline was below ``params.min_baseline``.
    """

    epipolar: NDArray[np.float64]
    depth: NDArray[np.float64]
    height: NDArray[np.float64]
    antiparallel: NDArray[np.float64]
    likelihood: NDArray[np.float64]
    valid: NDArray[np.bool_]
    static_camera: bool


def _unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.einsum("...i,...i->...", a, b)


def constraints(
    rays0: ArrayLike,
    rays1: ArrayLike,
    pose0: ArrayLike,
    pose1: ArrayLike,
    *,
    road: Road | None = None,
    params: Params | None = None,
) -> ConstraintResult:
    """Score the four spherical constraints for ray correspondences.

    Parameters
    ----------
    rays0, rays1 : array_like, shape (..., 3)
        ``g(u)`` and ``g(u')``: rays of the previous and the current frame, each in its own camera
        frame (any non-zero length).
    pose0, pose1 : array_like, shape (4, 4)
        ``world_from_cam`` of the previous and the current camera.
    road : Road, optional
        Road plane in the world frame; default ``z = 0``.
    params : Params, optional

    Returns
    -------
    ConstraintResult

    Raises
    ------
    ValueError
        Naming the argument, for rays of other shapes or poses that are not rigid 4x4 transforms.
    """
    p_cam = as_points(rays0, 3, "rays0")
    q_cam = as_points(rays1, 3, "rays1")
    if p_cam.shape != q_cam.shape:
        raise ValueError(f"rays1: expected the shape of rays0 {p_cam.shape}, got {q_cam.shape}")
    t0 = check_rigid(pose0, "pose0")
    t1 = check_rigid(pose1, "pose1")
    road = Road() if road is None else road
    params = Params() if params is None else params
    if not isinstance(road, Road):
        raise ValueError(f"road: expected a fisheyemotion.Road, got {type(road).__name__}")
    if not isinstance(params, Params):
        raise ValueError(f"params: expected a fisheyemotion.Params, got {type(params).__name__}")

    # Rays in the world frame: rotation is compensated here.
    with np.errstate(invalid="ignore", over="ignore"):
        p = _unit(p_cam @ t0[:3, :3].T)
        q = _unit(q_cam @ t1[:3, :3].T)
    finite = np.isfinite(p).all(axis=-1) & np.isfinite(q).all(axis=-1)
    baseline = t0[:3, 3] - t1[:3, 3]
    b = float(np.linalg.norm(baseline))
    zeros = np.zeros(p.shape[:-1])

    if b < params.min_baseline:
        xi = np.linalg.norm(np.cross(q, p), axis=-1)
        return _result(zeros, zeros, zeros, zeros, xi, finite, static=True)

    e = baseline / b
    n_raw = np.cross(p, e)
    sin_pe = np.linalg.norm(n_raw, axis=-1)
    valid = finite & (sin_pe > params.epipole_margin)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n_raw / sin_pe[..., None]
        w = (p - _dot(p, e)[..., None] * e) / sin_pe[..., None]

    # Planar epipolar constraint.
    qn = _dot(q, n)
    xi_e = np.abs(qn)

    # Angular coordinates on the epipolar great circle: e' at 0, p at Theta in (0, pi).
    q_pi = q - qn[..., None] * n
    has_dir = np.linalg.norm(q_pi, axis=-1) > _DEGENERATE
    theta = np.arctan2(sin_pe, _dot(p, e))
    phi = np.arctan2(_dot(q_pi, w), _dot(q_pi, e))  # scale-free: q_pi need not be unit

    # Positive depth: p'_Pi must lie on the arc [e', p].
    beyond_p = (phi > theta) | (phi < theta - np.pi)  # current camera: behind it
    xi_d = np.where(beyond_p, np.abs(np.sin(phi - theta)), 0.0)
    if params.depth_both_views:
        beyond_e = (phi < 0) & (phi >= theta - np.pi)  # previous camera: behind it
        xi_d = np.where(beyond_e, np.abs(np.sin(phi)), xi_d)

    # Positive height and anti-parallel: below the horizon, relative to the road point p'_r.
    down = -road.up
    eta = float(road.height(t0[:3, 3]))
    p_down, q_down = _dot(p, down), _dot(q, down)
    below = (p_down > params.horizon_margin) & (q_down > params.horizon_margin) & (eta > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        delta = np.where(below, eta / p_down, 0.0)
    # p'_r ~ b e' + delta p  =>  its angle from e' on the circle:
    phi_r = np.arctan2(delta * sin_pe, b + delta * np.cos(theta))
    on_arc = (phi >= 0) & (phi <= theta)
    deviation = np.abs(np.sin(phi - phi_r))  # |p'_Pi x p'_r|
    xi_h = np.where(below & on_arc & (phi > phi_r), np.maximum(deviation - params.lambda_h, 0), 0)
    if params.lambda_p_mode == "adaptive":
        lambda_p = params.lambda_p_ratio * np.abs(np.sin(theta - phi_r))  # |p'_r x p|
    else:
        lambda_p = params.lambda_p
    xi_p = np.where(below & on_arc & (phi < phi_r), np.maximum(deviation - lambda_p, 0), 0)

    # p' perpendicular to the epipolar plane: maximal epipolar deviation, no direction on it.
    xi_d, xi_h, xi_p = (np.where(has_dir, x, 0.0) for x in (xi_d, xi_h, xi_p))
    mu = params.weights
    likelihood = (mu[0] * xi_e + mu[1] * xi_d + mu[2] * xi_h + mu[3] * xi_p) / sum(mu)
    return _result(xi_e, xi_d, xi_h, xi_p, likelihood, valid, static=False)


def _result(xi_e, xi_d, xi_h, xi_p, likelihood, valid, *, static: bool) -> ConstraintResult:
    out = []
    for x in (xi_e, xi_d, xi_h, xi_p, likelihood):
        x = np.array(x, dtype=np.float64)
        x[~valid] = np.nan
        out.append(x)
    return ConstraintResult(*out, valid=np.asarray(valid, dtype=bool), static_camera=static)
