"""Deviations in units of measurement error: how far a cell is outside what its flow's error explains.

The constraints measure deviations as angles (sines) on the sphere. The same angle means very
different things across a fisheye image: near the epipole every static point moves little, so
a car ahead that closes in slowly deviates by a fraction of a degree, while a cell whose flow is
off by a pixel deviates as much anywhere. Dividing a deviation by the angular error of the
cell's flow makes it a significance (a z-score, after Klappstein et al., IV 2009):

    sigma_cell = sqrt(sigma_0^2 + var_cell(flow)) * alpha_cell
    z = xi / sigma_cell

``sigma_0`` (pixels) is the flow method's accuracy on a well-textured static surface;
``var_cell(flow)`` is the variance of the dense flow inside the cell (a cell straddling an
occlusion boundary or a poorly matched texture has discordant pixel flows); ``alpha_cell`` is
the camera's angle per pixel at the cell (it shrinks towards a fisheye's rim).

The poses are measured too. A position error ``sigma_x`` over a baseline ``b`` turns the
direction of travel by about ``sigma_t = sigma_x / b`` radians, which tilts a cell's epipolar
great circle (through the epipole and the cell's ray) by ``sigma_t / sin(theta)``, ``theta``
the ray's angle from the direction of travel; the static correspondence, ``phi`` (the
parallax) along that circle from the ray, then moves off it by

    sigma_pose = sigma_t * sin(phi) / sin(theta),

which the cell's error adds in quadrature (:func:`pose_sigma`). ``sin(phi) / sin(theta)`` is at
most about ``b / distance``, so the term matters where the baseline is short and the scene near:
a head-mounted camera's 2-3 mm between 30-Hz frames with millimetre poses (the direction of
travel known to tens of degrees) against a car's 1.4 m between frames 3 apart.

The detector uses significance for the positive-height and positive-depth terms: on a static
scene these two are quiet once the flow's error is accounted for (a static point can only
violate them through flow error), so a significant value there is motion even near the epipole
-- a preceding car that the raw angles never flag. The epipolar deviation is counted in sigmas
too (``Params.epipolar_significance``, a lower bar): a pedestrian crossing slowly or far ahead
leaves its arc by a fraction of the raw threshold but by several of its flow's sigmas; that
needs the poses' error in the model (below), or a head-mounted camera's millimetre baselines
flag the near static scene (``docs/evaluation.md``, *Epipolar significance*). The anti-parallel
term keeps its raw angle: static structure above the road (the anti-parallel ambiguity) makes
it large on static cells whatever the error model.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel
from .flow import grid_average

__all__ = ["cell_sigma", "pixel_angle", "pose_sigma"]


def pixel_angle(camera: CameraModel, pixels: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angle (radians) subtended by one pixel at each of ``pixels`` (..., 2): the mean of the
    angles to the next pixel right and down; NaN outside the camera's domain."""
    r0, ok0 = camera.unproject(pixels)
    angles = []
    for step in ((1.0, 0.0), (0.0, 1.0)):
        r1, ok1 = camera.unproject(pixels + np.asarray(step))
        cross = np.linalg.norm(np.cross(r0, r1), axis=-1)
        angles.append(np.where(ok0 & ok1, np.arctan2(cross, np.einsum("...i,...i", r0, r1)),
                               np.nan))
    return 0.5 * (angles[0] + angles[1])


def cell_sigma(flow: NDArray[np.float32], grid: int, angle: NDArray[np.float64], *,
               floor: float, mean: NDArray | None = None) -> NDArray[np.float64]:
    """Angular error of each cell's mean flow.

    Parameters
    ----------
    flow : ndarray, shape (H, W, 2)
        The dense flow.
    grid : int
        Cell size, pixels.
    angle : ndarray, shape (rows, cols)
        :func:`pixel_angle` at the cell centres.
    floor : float
        ``sigma_0``, pixels.
    mean : ndarray, shape (rows, cols, 2), optional
        The cells' mean flow, when the caller has it already.

    Returns
    -------
    ndarray, shape (rows, cols)
        Radians.
    """
    from ._grid_kernels import cell_variance  # numba on first use: a light import

    mean = grid_average(flow, grid) if mean is None else mean
    # Deviations from the cell mean (E[f^2] - E[f]^2 would cancel at 100-px flows).
    var = np.empty(mean.shape[:2])
    cell_variance(np.ascontiguousarray(flow), int(grid), np.ascontiguousarray(mean), var)
    return np.sqrt(floor * floor + var) * angle


def pose_sigma(rays0: NDArray[np.float64], parallax: NDArray[np.float64],
               pose0: NDArray[np.float64], pose1: NDArray[np.float64],
               position_sigma: float) -> NDArray[np.float64]:
    """Angular deviation from the epipolar arc that the poses' position error explains.

    ``sigma_pose = min(1, position_sigma / b) * sin(phi) / sin(theta)``: ``b`` the baseline,
    ``phi`` the angle between the two rays in the world frame (the parallax), ``theta`` the
    first ray's angle from the direction of travel (module docstring).

    Parameters
    ----------
    rays0 : ndarray, shape (..., 3)
        Unit rays of the cells in the first camera's frame.
    parallax : ndarray, shape (...)
        ``sin(phi)``, as :func:`fisheyemotion.static_scene.triangulate_range` gives it with
        ``with_parallax=True``.
    pose0, pose1 : ndarray, shape (4, 4)
        ``world_from_cam`` of the two frames.
    position_sigma : float
        The poses' position error between the two frames, in the poses' units.

    Returns
    -------
    ndarray, shape (...)
        Radians; NaN where the parallax is, 0 for a baseline of 0 or ``position_sigma`` 0.
    """
    baseline = pose1[:3, 3] - pose0[:3, 3]
    b = float(np.linalg.norm(baseline))
    if b == 0.0 or position_sigma == 0.0:
        return parallax * 0.0
    travel = pose0[:3, :3].T @ (baseline / b)  # in the first camera's frame
    sin_theta = rays0 @ travel  # cos(theta), turned into sin(theta) in place
    sin_theta *= sin_theta
    np.subtract(1.0, sin_theta, out=sin_theta)
    np.sqrt(sin_theta, out=sin_theta)
    with np.errstate(invalid="ignore", divide="ignore"):
        return min(1.0, position_sigma / b) * parallax / sin_theta
