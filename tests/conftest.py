"""Shared test set-up: fixed hypothesis seeds and the bundled calibration fixtures."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile(
    "ci", derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow],
    max_examples=60,
)
settings.load_profile("ci")

DATA = Path(__file__).parent / "data"
CALIB = DATA / "calib"


@pytest.fixture
def calib_dir() -> Path:
    return CALIB
