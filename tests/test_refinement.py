"""The rotation helpers of pose refinement: slerp between two transforms and the mean of
rotations (the anchor), against SciPy and by their defining properties."""

from __future__ import annotations

import numpy as np
from fisheyemotion.calib.transforms import (
    interpolate_transform,
    make_transform,
    mean_rotation,
    rotation_angle,
)
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

from .scenes import random_rotation, rotation


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), weight=st.floats(0.0, 1.0))
def test_interpolate_transform_is_scipys_slerp_and_a_linear_translation(seed, weight):
    rng = np.random.default_rng(seed)
    a = make_transform(random_rotation(rng), rng.normal(size=3) * 10)
    # Any rotation but (near) half a turn away, where slerp has two answers.
    b = make_transform(a[:3, :3] @ rotation(rng.normal(size=3), rng.uniform(0, 3.0)),
                       rng.normal(size=3) * 10)
    got = interpolate_transform(a, b, weight)
    want = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([a[:3, :3], b[:3, :3]])))([weight])
    assert rotation_angle(got[:3, :3].T @ want.as_matrix()[0]) < 1e-9
    np.testing.assert_allclose(got[:3, 3], a[:3, 3] + weight * (b[:3, 3] - a[:3, 3]), atol=1e-9)
    np.testing.assert_allclose(got[3], [0, 0, 0, 1])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 12),
       spread=st.floats(0.0, np.radians(5.0)))
def test_the_mean_of_rotations_symmetric_about_one_is_that_one(seed, n, spread):
    rng = np.random.default_rng(seed)
    centre = random_rotation(rng)
    offsets = [rotation(rng.normal(size=3), rng.uniform(0, spread)) for _ in range(n)]
    # Each offset with its inverse: symmetric about the centre on both sides.
    rotations = np.stack([centre @ o for o in offsets] + [centre @ o.T for o in offsets])
    assert rotation_angle(mean_rotation(rotations).T @ centre) < 1e-9


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 12))
def test_the_mean_of_rotations_is_a_rotation_that_turns_with_them(seed, n):
    rng = np.random.default_rng(seed)
    rotations = np.stack([rotation(rng.normal(size=3), rng.uniform(0, 0.2)) for _ in range(n)])
    mean = mean_rotation(rotations)
    np.testing.assert_allclose(mean.T @ mean, np.eye(3), atol=1e-12)
    assert np.linalg.det(mean) > 0
    turn = random_rotation(rng)
    assert rotation_angle(mean_rotation(turn @ rotations).T @ (turn @ mean)) < 1e-9
    assert rotation_angle(mean_rotation(rotations @ turn).T @ (mean @ turn)) < 1e-9
    # Within 1e-4 deg of SciPy's (quaternion) mean for spreads of a few degrees.
    scipy_mean = Rotation.from_matrix(rotations).mean().as_matrix()
    assert np.degrees(rotation_angle(mean.T @ scipy_mean)) < 1e-4
