"""One registry of camera models, keyed by canonical name (as COLMAP's ``CAMERA_MODEL_CASES``)."""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

from .base import CameraModel

_T = TypeVar("_T", bound=type[CameraModel])

#: canonical name -> model class, in registration order.
MODELS: dict[str, type[CameraModel]] = {}


def register(cls: _T) -> _T:
    """Class decorator adding a model to :data:`MODELS` under ``cls.name``."""
    if not cls.name or cls.name in MODELS:
        raise ValueError(f"register: model name {cls.name!r} is empty or already registered")
    MODELS[cls.name] = cls
    return cls


def model_class(name: str) -> type[CameraModel]:
    """The model class registered as ``name``; ValueError listing the known names otherwise."""
    try:
        return MODELS[name]
    except (KeyError, TypeError):
        known = ", ".join(sorted(MODELS))
        raise ValueError(f"model: unknown camera model {name!r}; expected one of {known}") from None


def create(name: str, **params: Any) -> CameraModel:
    """Build the model ``name`` from keyword parameters (``width`` and ``height`` included)."""
    cls = model_class(name)
    known = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(params) - set(known))
    if unknown:
        raise ValueError(f"{name}: unknown parameter(s) {unknown}; expected {known}")
    return cls(**params)
