"""A naive per-point Python loop over the paper's formulas: the peer of the vectorised engine.

Kept in benchmarks/ only. Scalar ``math`` code written from docs/geometry.md; it also serves as an
independent check of the engine's values in ``test_bench_engine.py``.
"""

from __future__ import annotations

import math


def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _norm(a):
    return math.sqrt(_dot(a, a))


def _rot(r, v):
    return tuple(r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2] for i in range(3))


def naive_likelihood(rays0, rays1, pose0, pose1, *, lambda_h=0.001, lambda_p=0.001,
                     weights=(1.0, 1.0, 0.2, 0.2), margin=1e-3):
    """Likelihood per ray pair (road z = 0, paper's constraints, depth in both views)."""
    r0 = [list(row[:3]) for row in pose0[:3]]
    r1 = [list(row[:3]) for row in pose1[:3]]
    c0 = tuple(pose0[i][3] for i in range(3))
    c1 = tuple(pose1[i][3] for i in range(3))
    base = _sub(c0, c1)
    b = _norm(base)
    e = (base[0] / b, base[1] / b, base[2] / b)
    eta = c0[2]
    out = []
    for ray0, ray1 in zip(rays0, rays1, strict=True):
        p = _rot(r0, ray0)
        q = _rot(r1, ray1)
        pn, qn_ = _norm(p), _norm(q)
        p = (p[0] / pn, p[1] / pn, p[2] / pn)
        q = (q[0] / qn_, q[1] / qn_, q[2] / qn_)
        n = _cross(p, e)
        s = _norm(n)
        if s <= margin:
            out.append(float("nan"))
            continue
        n = (n[0] / s, n[1] / s, n[2] / s)
        pe = _dot(p, e)
        w = ((p[0] - pe * e[0]) / s, (p[1] - pe * e[1]) / s, (p[2] - pe * e[2]) / s)
        qn = _dot(q, n)
        xi_e = abs(qn)
        qp = (q[0] - qn * n[0], q[1] - qn * n[1], q[2] - qn * n[2])
        theta = math.atan2(s, pe)
        phi = math.atan2(_dot(qp, w), _dot(qp, e))
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
