"""Naive per-point Python loops over the paper's formulas: the peers of the numba engine.

Kept in benchmarks/ only. One loop, written from docs/geometry.md with angles (``atan2``), run
with two sets of 3-vector primitives: scalar ``math`` on tuples (the fastest plain-Python form) and
numpy on 3-element arrays (``np.cross``, ``np.linalg.norm``: what a per-point translation of
vectorised numpy code looks like). It also serves as an independent check of the engine's values
in ``test_bench_engine.py``.
"""

from __future__ import annotations

import math

import numpy as np


class _MathOps:
    """3-vectors as tuples, scalar ``math``."""

    @staticmethod
    def vec(a):
        return (float(a[0]), float(a[1]), float(a[2]))

    @staticmethod
    def sub(a, b):
        return (a[0] - b[0], a[1] - b[1], a[2] - b[2])

    @staticmethod
    def scale(a, k):
        return (a[0] * k, a[1] * k, a[2] * k)

    @staticmethod
    def dot(a, b):
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]

    @staticmethod
    def cross(a, b):
        return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])

    @classmethod
    def norm(cls, a):
        return math.sqrt(cls.dot(a, a))

    @staticmethod
    def rotation(pose):
        return [list(row[:3]) for row in pose[:3]]

    @staticmethod
    def rot(r, v):
        return tuple(r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2] for i in range(3))


class _NumpyOps:
    """3-vectors as numpy arrays, numpy primitives."""

    vec = staticmethod(np.asarray)
    sub = staticmethod(np.subtract)
    scale = staticmethod(np.multiply)
    dot = staticmethod(np.dot)
    cross = staticmethod(np.cross)
    norm = staticmethod(np.linalg.norm)
    rot = staticmethod(np.dot)

    @staticmethod
    def rotation(pose):
        return np.asarray(pose)[:3, :3]


OPS = {"math": _MathOps, "numpy": _NumpyOps}


def naive_likelihood(rays0, rays1, pose0, pose1, *, ops="math", lambda_h=0.001, lambda_p=0.001,
                     weights=(1.0, 1.0, 0.2, 0.2), margin=1e-3):
    """Likelihood per ray pair (road z = 0, paper's constraints, depth in both views)."""
    o = OPS[ops]
    r0, r1 = o.rotation(pose0), o.rotation(pose1)
    c0 = o.vec([pose0[i][3] for i in range(3)])
    c1 = o.vec([pose1[i][3] for i in range(3)])
    base = o.sub(c0, c1)
    b = o.norm(base)
    e = o.scale(base, 1.0 / b)
    eta = c0[2]
    out = []
    for ray0, ray1 in zip(rays0, rays1, strict=True):
        p = o.rot(r0, ray0)
        q = o.rot(r1, ray1)
        p = o.scale(p, 1.0 / o.norm(p))
        q = o.scale(q, 1.0 / o.norm(q))
        n = o.cross(p, e)
        s = o.norm(n)
        if s <= margin:
            out.append(float("nan"))
            continue
        n = o.scale(n, 1.0 / s)
        pe = o.dot(p, e)
        w = o.scale(o.sub(p, o.scale(e, pe)), 1.0 / s)
        qn = o.dot(q, n)
        xi_e = abs(qn)
        qp = o.sub(q, o.scale(n, qn))
        theta = math.atan2(s, pe)
        phi = math.atan2(o.dot(qp, w), o.dot(qp, e))
        xi_d = 0.0
        if phi > theta or phi < theta - math.pi:
            xi_d = abs(math.sin(phi - theta))
        elif phi < 0:
            xi_d = abs(math.sin(phi))
        xi_h = xi_p = 0.0
        if -p[2] > 0 and -q[2] > 0 and eta > 0 and 0 <= phi <= theta:
            delta = eta / -p[2]
            phi_r = math.atan2(delta * s, b + delta * math.cos(theta))
            dev = abs(math.sin(phi - phi_r))
            if phi > phi_r:
                xi_h = max(dev - lambda_h, 0.0)
            elif phi < phi_r:
                xi_p = max(dev - lambda_p, 0.0)
        mu = weights
        out.append((mu[0] * xi_e + mu[1] * xi_d + mu[2] * xi_h + mu[3] * xi_p) / sum(mu))
    return out
