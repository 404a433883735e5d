"""Fit one camera model to another (least squares on pixels over the reference's valid rays)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .base import CameraModel, pixel_grid
from .registry import model_class

# Starting values of the model-specific parameters.
_START = {"xi": 0.0, "alpha": 0.55, "beta": 1.0, "k1": 0.0, "k2": 0.0, "k3": 0.0, "k4": 0.0}
_START_BY_MODEL = {"unified": {"xi": 1.0}}


def fit_model(reference: CameraModel, name: str, *, step: int = 8,
              max_theta: float | None = None) -> tuple[CameraModel, float]:
    """The model ``name`` that best reproduces ``reference``'s pixels.

    Parameters
    ----------
    reference : CameraModel
    name : str
        Registry name of the model to fit (``double_sphere``, ``enhanced_unified``...).
    step : int
        Pixel stride of the reference's valid pixels used as samples.
    max_theta : float, optional
        Only rays up to this angle (radians); default: all of the reference's valid pixels.

    Returns
    -------
    camera : CameraModel
    rms_px : float
        Root-mean-square pixel error over the samples (rays the fit cannot project count with
        the image diagonal).
    """
    from scipy.optimize import least_squares  # not imported with the package

    cls = model_class(name)
    grid = pixel_grid(reference.width, reference.height)[::step, ::step].reshape(-1, 2)
    rays, valid = reference.unproject(grid)
    keep = valid if max_theta is None else valid & (np.arccos(np.clip(rays[:, 2], -1, 1)) <= max_theta)
    rays, pixels = rays[keep], grid[keep]
    fx, fy, cx, cy = reference._affine()
    start = {"fx": fx, "fy": fy, "cx": cx, "cy": cy, **_START, **_START_BY_MODEL.get(name, {})}
    names = [n for n in cls.param_names if n in start]
    unknown = [n for n in cls.param_names if n not in start and not hasattr(reference, n)]
    if unknown:
        raise ValueError(f"name: fitting {name} to a {reference.name} camera is not supported "
                         f"(no starting value for {unknown})")
    fixed = {n: getattr(reference, n) for n in cls.param_names if n not in start}
    if reference.name == name:  # refit of the same model: start from the answer
        start.update({n: getattr(reference, n) for n in names})
    x0 = np.array([start[n] for n in names])
    penalty = float(np.hypot(reference.width, reference.height))

    def build(x: NDArray) -> CameraModel | None:
        try:
            return cls(**dict(zip(names, x, strict=True)), **fixed, width=reference.width,
                       height=reference.height)
        except ValueError:
            return None

    def residual(x: NDArray) -> NDArray:
        cam = build(x)
        if cam is None:
            return np.full(2 * len(rays), penalty)
        proj, ok = cam.project(rays)
        res = np.where(ok[:, None], proj - pixels, penalty)
        return res.ravel()

    sol = least_squares(residual, x0, method="trf", x_scale="jac", max_nfev=400)
    cam = build(sol.x)
    if cam is None:
        raise ValueError(f"name: could not fit a valid {name} camera to the reference")
    rms = float(np.sqrt(np.mean(residual(sol.x).reshape(-1, 2) ** 2 * 2)))
    return cam, rms
