"""The constraint engine (numba) vs naive per-point Python loops (math and numpy), in rays per second."""

from __future__ import annotations

import numpy as np
import pytest
from fisheyemotion.calib.transforms import make_transform

import fisheyemotion as fm

from .naive import naive_likelihood


def _rays(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    pose0 = make_transform(np.array([[0, 0, 1.0], [-1, 0, 0], [0, -1, 0]]), [0, 0, 1.0])
    pose1 = pose0.copy()
    pose1[0, 3] += 0.3
    x = np.c_[rng.uniform(2, 30, n), rng.uniform(-10, 10, n), rng.uniform(0, 3, n)]
    x1 = x + rng.normal(0, 0.05, x.shape)

    def rays(points, pose):
        d = (points - pose[:3, 3]) @ pose[:3, :3]
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    return rays(x, pose0), rays(x1, pose1), pose0, pose1


@pytest.mark.benchmark(group="engine-12k")
def test_engine_12k(benchmark):
    r0, r1, p0, p1 = _rays(12_288)
    res = benchmark(fm.constraints, r0, r1, p0, p1)
    benchmark.extra_info["rays"] = len(r0)
    assert res.valid.mean() > 0.99


@pytest.mark.benchmark(group="engine-307k")
def test_engine_307k(benchmark):
    r0, r1, p0, p1 = _rays(307_200)
    benchmark(fm.constraints, r0, r1, p0, p1)
    benchmark.extra_info["rays"] = len(r0)


@pytest.mark.benchmark(group="engine-12k")
@pytest.mark.parametrize("ops", ["math", "numpy"])
def test_naive_loop_12k(benchmark, ops):
    r0, r1, p0, p1 = _rays(12_288)
    lists = (r0.tolist(), r1.tolist(), p0.tolist(), p1.tolist())
    out = benchmark.pedantic(naive_likelihood, args=lists, kwargs={"ops": ops}, rounds=3,
                             iterations=1)
    benchmark.extra_info["rays"] = len(r0)
    ours = fm.constraints(r0, r1, p0, p1).likelihood
    np.testing.assert_allclose(np.array(out), ours, rtol=1e-9, atol=1e-12)


@pytest.mark.benchmark(group="engine-307k")
@pytest.mark.parametrize("ops", ["math", "numpy"])
def test_naive_loop_307k(benchmark, ops):
    r0, r1, p0, p1 = _rays(307_200)
    lists = (r0.tolist(), r1.tolist(), p0.tolist(), p1.tolist())
    benchmark.pedantic(naive_likelihood, args=lists, kwargs={"ops": ops}, rounds=1, iterations=1)
    benchmark.extra_info["rays"] = len(r0)
