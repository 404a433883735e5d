"""Typed access to parsed calibration data, with errors that name the file and the field."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..base import CameraModel
from ..errors import CalibrationError
from ..registry import model_class
from ..transforms import check_rigid

#: Pixels: wider or taller images are not camera images (and would exhaust memory).
MAX_IMAGE_SIZE = 32768


class Fields:
    """Reads values out of a parsed document; every failure is a :class:`CalibrationError`.

    Parameters
    ----------
    source : str
        The file name used in error messages.
    """

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, field: str, expected: str) -> CalibrationError:
        return CalibrationError(field, expected, source=self.source)

    def mapping(self, value: Any, field: str) -> dict:
        if not isinstance(value, dict):
            raise self.fail(field, f"expected a mapping, got {type(value).__name__}")
        return value

    def get(self, mapping: Any, key: str, field: str) -> Any:
        where = f"{field}.{key}" if field else key
        m = self.mapping(mapping, field or "(top level)")
        if key not in m:
            raise self.fail(where, "missing")
        return m[key]

    def number(self, value: Any, field: str) -> float:
        if isinstance(value, str):
            try:
                value = float(value)
            except ValueError:
                raise self.fail(field, f"expected a number, got {value[:40]!r}") from None
        if isinstance(value, bool) or not isinstance(value, int | float | np.number):
            raise self.fail(field, f"expected a number, got {type(value).__name__}")
        try:
            out = float(value)
        except OverflowError:
            raise self.fail(field, "expected a finite number, got an integer too large for "
                            "a float") from None
        if not math.isfinite(out):
            raise self.fail(field, f"expected a finite number, got {value!r}")
        return out

    def numbers(self, value: Any, field: str, count: int | None = None) -> list[float]:
        if isinstance(value, np.ndarray):
            value = value.ravel().tolist()
        if not isinstance(value, list | tuple):
            raise self.fail(field, f"expected a list of numbers, got {type(value).__name__}")
        if count is not None and len(value) != count:
            raise self.fail(field, f"expected {count} numbers, got {len(value)}")
        return [self.number(v, f"{field}[{i}]") for i, v in enumerate(value)]

    def size(self, value: Any, field: str) -> int:
        out = self.number(value, field)
        if out <= 0 or not out.is_integer() or out > MAX_IMAGE_SIZE:
            raise self.fail(field, f"expected a positive integer image size up to "
                            f"{MAX_IMAGE_SIZE}, got {out:g}")
        return int(out)

    def string(self, value: Any, field: str) -> str:
        if not isinstance(value, str):
            raise self.fail(field, f"expected a string, got {type(value).__name__}")
        return value

    def transform(self, value: Any, field: str) -> NDArray[np.float64]:
        """A 4x4 rigid transform given as 4 rows of 4 numbers (or 16 numbers)."""
        if isinstance(value, list) and len(value) == 4 and all(isinstance(r, list) for r in value):
            rows = [self.numbers(r, f"{field}[{i}]", 4) for i, r in enumerate(value)]
        else:
            flat = self.numbers(value, field, 16)
            rows = [flat[i : i + 4] for i in range(0, 16, 4)]
        try:
            return check_rigid(np.array(rows), field)
        except ValueError as exc:
            raise self.fail(field, str(exc).split(": ", 1)[-1]) from None

    def camera(self, model: str, field: str, **params: Any) -> CameraModel:
        """Build a registered model; a parameter out of range names the file and ``field``."""
        try:
            return model_class(model)(**params)
        except ValueError as exc:
            raise self.fail(field, str(exc)) from None
