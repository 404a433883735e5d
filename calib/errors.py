"""Exceptions raised by :mod:`fisheyemotion.calib`."""

from __future__ import annotations


class CalibrationError(ValueError):
    """A calibration file or camera parameter is malformed.

    The message names the file (when there is one), the field, and what was expected, e.g.
    ``calib.yaml: cam0.intrinsics: expected 6 numbers for camera_model 'ds', got 5``.
    """

    def __init__(self, field: str, expected: str, *, source: str | None = None) -> None:
        # Bounded: the values quoted come from files that may be hostile (a YAML 'billion
        # laughs' expands to gigabytes).
        field, expected = _cut(str(field), 200), _cut(str(expected), 400)
        self.source = source
        self.field = field
        self.expected = expected
        where = f"{source}: " if source else ""
        super().__init__(f"{where}{field}: {expected}")


def _cut(text: str, limit: int) -> str:
    return text if len(text) <= limit else text[:limit] + f"... ({len(text) - limit} more characters)"
