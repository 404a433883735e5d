"""Input checks shared by every camera model and by the engine (one place, one wording)."""

from __future__ import annotations

import math
from numbers import Real

import numpy as np
from numpy.typing import ArrayLike, NDArray


def as_points(value: ArrayLike, dim: int, name: str) -> NDArray[np.float64]:
    """Return ``value`` as a float64 array of shape ``(..., dim)``.

    Raises
    ------
    ValueError
        Naming ``name`` when the value is not real-numbered or its last axis is not ``dim``.
        Non-finite *elements* are allowed: models report them as invalid, not as errors.
    """
    try:
        arr = np.asarray(value)
    except Exception as exc:  # ragged lists and the like
        raise ValueError(f"{name}: expected a real array of shape (..., {dim}); {exc}") from None
    if arr.dtype.kind not in "iuf":
        raise ValueError(
            f"{name}: expected a real (integer or float) array of shape (..., {dim}), "
            f"got dtype {arr.dtype}"
        )
    if arr.ndim == 0 or arr.shape[-1] != dim:
        raise ValueError(f"{name}: expected an array of shape (..., {dim}), got shape {arr.shape}")
    return arr.astype(np.float64, copy=False)


def check_real(name: str, value: object, *, owner: str) -> float:
    """Return ``value`` as a finite float or raise a ValueError naming ``owner.name``."""
    if isinstance(value, bool) or not isinstance(value, Real | np.number):
        raise ValueError(f"{owner}.{name}: expected a finite real number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise ValueError(f"{owner}.{name}: expected a finite real number, got {value!r}")
    return out


def check_size(name: str, value: object, *, owner: str) -> int:
    """Return ``value`` as a positive int (image width or height)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer | float | np.floating):
        raise ValueError(f"{owner}.{name}: expected a positive integer, got {value!r}")
    if isinstance(value, float | np.floating) and not float(value).is_integer():
        raise ValueError(f"{owner}.{name}: expected a positive integer, got {value!r}")
    out = int(value)
    if out <= 0:
        raise ValueError(f"{owner}.{name}: expected a positive integer, got {value!r}")
    return out
