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

The detector uses significance for the positive-height and positive-depth terms: on a static
scene these two are quiet once the flow's error is accounted for (a static point can only
violate them through flow error), so a significant value there is motion even near the epipole
-- a preceding car that the raw angles never flag. The epipolar and anti-parallel terms keep
their raw angles: flow errors that are wrong but self-consistent (repeated textures) and static
structure above the road (the anti-parallel ambiguity) make them large on static cells whatever
the error model (``docs/evaluation.md``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel
from .flow import grid_average

__all__ = ["cell_sigma", "pixel_angle"]


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
