"""Double sphere and EUCM against golden values from an independent 50-digit implementation.

The values in ``data/golden/ds_eucm.json`` were computed once by ``data/golden/make_golden.py``
(mpmath, scalar, straight from the papers' equations; no code shared with the package).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from fisheyemotion import calib

from .conftest import DATA

GOLDEN = json.loads((DATA / "golden" / "ds_eucm.json").read_text())


def _camera(name: str) -> calib.CameraModel:
    params = {k: (float(v) if isinstance(v, str) else v)
              for k, v in GOLDEN["models"][name]["params"].items()}
    return calib.create(name, **params)


@pytest.mark.parametrize("name", sorted(GOLDEN["models"]))
def test_projection_matches_golden(name):
    cam = _camera(name)
    points = GOLDEN["models"][name]["points"]
    rays = np.array([p["ray"] for p in points])
    pixels, valid = cam.project(rays)
    assert valid.all()
    np.testing.assert_allclose(pixels, [p["pixel"] for p in points], rtol=0, atol=1e-9)


@pytest.mark.parametrize("name", sorted(GOLDEN["models"]))
def test_unprojection_matches_golden(name):
    cam = _camera(name)
    points = GOLDEN["models"][name]["points"]
    rays, valid = cam.unproject(np.array([p["pixel"] for p in points]))
    assert valid.all()
    np.testing.assert_allclose(rays, [p["unprojected"] for p in points], rtol=0, atol=1e-11)
    # The golden implementation itself round-trips: the angles span 0 to 120 degrees.
    np.testing.assert_allclose(rays, [p["ray"] for p in points], rtol=0, atol=1e-11)
    assert max(p["theta_deg"] for p in points) > 115
