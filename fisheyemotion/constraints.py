"""The spherical constraint engine (Mariotti & Hughes, ITSC 2019), derived on the epipolar circle.

Input checks and the static-camera case live here; the per-ray geometry is the numba kernel in
``_engine_kernel.py``.

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

from . import _warmup
from .calib._arrays import as_points
from .calib.transforms import check_rigid, rotate
from .params import Params
from .road import Road


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


_NO_ARC = np.empty((0, 3))  # constraint_kernel's arc output, not wanted


def _unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)


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

    shape = p_cam.shape[:-1]
    p_flat = np.ascontiguousarray(p_cam.reshape(-1, 3))
    q_flat = np.ascontiguousarray(q_cam.reshape(-1, 3))
    baseline = t0[:3, 3] - t1[:3, 3]
    b = float(np.linalg.norm(baseline))

    if b < params.min_baseline:
        # Camera standing still: the angle the rotation-compensated ray moved.
        with np.errstate(invalid="ignore", over="ignore"):
            p = _unit(rotate(p_flat, t0[:3, :3]))
            q = _unit(rotate(q_flat, t1[:3, :3]))
        finite = np.isfinite(p).all(axis=-1) & np.isfinite(q).all(axis=-1)
        xi = np.linalg.norm(np.cross(q, p), axis=-1)
        zeros = np.zeros(len(p))
        return _result(zeros, zeros, zeros, zeros, xi, finite, static=True, shape=shape)

    out = np.empty((5, len(p_flat)))
    valid = np.empty(len(p_flat), dtype=bool)
    from ._engine_kernel import constraint_kernel  # numba on first use: a light import

    _warmup.wait()
    constraint_kernel(
        p_flat, q_flat, np.ascontiguousarray(t0[:3, :3]), np.ascontiguousarray(t1[:3, :3]),
        baseline / b, b, -road.up, float(road.height(t0[:3, 3])) if road.known else 0.0,
        params.lambda_h,
        params.lambda_p, params.lambda_p_mode == "adaptive", params.lambda_p_ratio,
        params.depth_both_views, params.epipole_margin, params.horizon_margin,
        np.asarray(params.weights, dtype=np.float64), out, valid, _NO_ARC)
    xi_e, xi_d, xi_h, xi_p, likelihood = (x.reshape(shape) for x in out)
    return ConstraintResult(xi_e, xi_d, xi_h, xi_p, likelihood, valid.reshape(shape),
                            static_camera=False)


def nearest_static_ray(rays0: NDArray[np.float64], rays1: NDArray[np.float64], pose0: NDArray,
                       pose1: NDArray) -> NDArray[np.float64]:
    """The current ray of a static point nearest to ``rays1``: ``p'`` projected onto its
    epipolar circle and clamped to the arc from ``e'`` (``lambda -> 0``) to ``p``
    (``lambda -> inf``) of the module doc, in the current camera's frame (the engine kernel's
    decomposition ``u = a e' + c p``: ``a < 0`` gives ``p``, ``c < 0`` gives ``e'``).

    Its epipolar and depth deviations are 0; its height and anti-parallel ones are those of the
    static point at that range.

    Parameters
    ----------
    rays0, rays1 : ndarray of float64, shape (n, 3)
        Unit rays in the previous and current camera frames.
    pose0, pose1 : ndarray, shape (4, 4)
        ``world_from_cam`` of the two cameras (validated by the caller).

    Returns
    -------
    ndarray of float64, shape (n, 3)
        Unit rays; NaN where the epipolar plane is undefined (``p`` along ``e'``, or no
        baseline) or ``p'`` is normal to it.
    """
    p_flat = np.ascontiguousarray(rays0, dtype=np.float64)
    arc = np.full(p_flat.shape, np.nan)
    baseline = pose0[:3, 3] - pose1[:3, 3]
    b = float(np.linalg.norm(baseline))
    if not b > 0 or len(p_flat) == 0:
        return arc
    from ._engine_kernel import constraint_kernel  # numba on first use: a light import

    _warmup.wait()
    # Only the arc is wanted: no road (eta 0), no dead bands, no epipole margin.
    constraint_kernel(
        p_flat, np.ascontiguousarray(rays1, dtype=np.float64),
        np.ascontiguousarray(pose0[:3, :3]), np.ascontiguousarray(pose1[:3, :3]),
        baseline / b, b, np.array([0.0, 0.0, -1.0]), 0.0, 0.0, 0.0, False, 0.0, True, 0.0, 0.0,
        np.ones(4), np.empty((5, len(p_flat))), np.empty(len(p_flat), dtype=bool), arc)
    return arc


def _result(xi_e, xi_d, xi_h, xi_p, likelihood, valid, *, static: bool,
            shape: tuple[int, ...]) -> ConstraintResult:
    out = []
    for x in (xi_e, xi_d, xi_h, xi_p, likelihood):
        x = np.array(x, dtype=np.float64)
        x[~valid] = np.nan
        out.append(x.reshape(shape))
    return ConstraintResult(*out, valid=np.asarray(valid, dtype=bool).reshape(shape),
                            static_camera=static)
