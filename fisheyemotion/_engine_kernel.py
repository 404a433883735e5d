"""The per-ray kernel of the constraint engine (numba): one pass, no temporaries.

The geometry is that of ``docs/geometry.md`` written without trigonometry: the projected current
ray ``u = p'_Pi / |p'_Pi|`` is decomposed on the epipolar circle as ``u = a e' + c p``; the angle
orderings of the derivation become sign tests on ``a``, ``c`` and ``c b - delta a``, and every
``|sin|`` of an angle difference is the norm of a cross product of unit vectors.
"""

from __future__ import annotations

import math

import numba
import numpy as np

_DEGENERATE = 1e-12
_UNIT_TOLERANCE = 4e-16


# error_model="numpy": IEEE division (no zero checks in the loop); fastmath only contracts to FMA,
# ignores the sign of zero and uses reciprocals -- never assumes away NaN or infinity, which the
# validity tests below rely on.
@numba.njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract", "nsz", "arcp"})
def constraint_kernel(p_cam, q_cam, r0, r1, e, b, down, eta, lambda_h, lambda_p, adaptive,
                      lambda_p_ratio, both_views, epipole_margin, horizon_margin, weights, out,
                      valid, arc):
    """Fill ``out`` (5, N): xi_e, xi_d, xi_h, xi_p, likelihood (NaN where invalid), and
    ``valid`` (N,); and, if ``arc`` is (N, 3) rather than (0, 3), the nearest static ray: ``u``
    clamped to the arc from ``e'`` to ``p``, in the current camera's frame (NaN where ``u`` is
    undefined).

    ``p_cam``, ``q_cam``: (N, 3) rays in their camera frames; ``r0``, ``r1``: world_from_cam
    rotations; ``e``: unit vector from the current to the previous centre, ``b`` the baseline;
    ``down``: unit world down; ``eta``: previous camera height above the road.
    """
    nan = np.nan
    inv_mu = 1.0 / (weights[0] + weights[1] + weights[2] + weights[3])
    with_arc = arc.shape[0] == p_cam.shape[0]
    for i in range(p_cam.shape[0]):
        # Rays in the world frame, unit length.
        px = r0[0, 0] * p_cam[i, 0] + r0[0, 1] * p_cam[i, 1] + r0[0, 2] * p_cam[i, 2]
        py = r0[1, 0] * p_cam[i, 0] + r0[1, 1] * p_cam[i, 1] + r0[1, 2] * p_cam[i, 2]
        pz = r0[2, 0] * p_cam[i, 0] + r0[2, 1] * p_cam[i, 1] + r0[2, 2] * p_cam[i, 2]
        qx = r1[0, 0] * q_cam[i, 0] + r1[0, 1] * q_cam[i, 1] + r1[0, 2] * q_cam[i, 2]
        qy = r1[1, 0] * q_cam[i, 0] + r1[1, 1] * q_cam[i, 1] + r1[1, 2] * q_cam[i, 2]
        qz = r1[2, 0] * q_cam[i, 0] + r1[2, 1] * q_cam[i, 1] + r1[2, 2] * q_cam[i, 2]
        # g(u) gives unit rays (and rotations keep them so): normalise only when the squared
        # norm is off by more than rounding; normalising then would change the ray by < 1 ulp.
        pn2 = px * px + py * py + pz * pz
        if abs(pn2 - 1.0) > _UNIT_TOLERANCE:
            pn = 1.0 / math.sqrt(pn2)
            px, py, pz = px * pn, py * pn, pz * pn
        qn2 = qx * qx + qy * qy + qz * qz
        if abs(qn2 - 1.0) > _UNIT_TOLERANCE:
            qn_ = 1.0 / math.sqrt(qn2)
            qx, qy, qz = qx * qn_, qy * qn_, qz * qn_
        # Epipolar plane normal n' = p x e' / |p x e'|.
        nx = py * e[2] - pz * e[1]
        ny = pz * e[0] - px * e[2]
        nz = px * e[1] - py * e[0]
        s = math.sqrt(nx * nx + ny * ny + nz * nz)
        if not (s > epipole_margin) or not math.isfinite(qx + qy + qz):
            for j in range(5):
                out[j, i] = nan
            valid[i] = False
            if with_arc:
                arc[i, 0] = arc[i, 1] = arc[i, 2] = nan
            continue
        inv_s = 1.0 / s
        nx, ny, nz = nx * inv_s, ny * inv_s, nz * inv_s
        qdn = qx * nx + qy * ny + qz * nz
        xi_e = abs(qdn)
        xi_d = 0.0
        xi_h = 0.0
        xi_p = 0.0
        ux, uy, uz = qx - qdn * nx, qy - qdn * ny, qz - qdn * nz
        ul = math.sqrt(ux * ux + uy * uy + uz * uz)
        wx = wy = wz = nan  # the nearest static ray, world frame
        if ul > _DEGENERATE:
            inv_ul = 1.0 / ul
            ux, uy, uz = ux * inv_ul, uy * inv_ul, uz * inv_ul
            k = px * e[0] + py * e[1] + pz * e[2]
            ue = ux * e[0] + uy * e[1] + uz * e[2]
            up = ux * px + uy * py + uz * pz
            a = (ue - k * up) * inv_s * inv_s  # u = a e' + c p
            c = (up - k * ue) * inv_s * inv_s
            if a < 0.0:  # beyond p: the point at infinity
                wx, wy, wz = px, py, pz
            elif c < 0.0:  # beyond e': the point at the previous centre
                wx, wy, wz = e[0], e[1], e[2]
            else:
                wx, wy, wz = ux, uy, uz
            if a < 0.0:  # behind the current camera: |u x p|
                cx_ = uy * pz - uz * py
                cy_ = uz * px - ux * pz
                cz_ = ux * py - uy * px
                xi_d = math.sqrt(cx_ * cx_ + cy_ * cy_ + cz_ * cz_)
            elif c < 0.0 and both_views:  # behind the previous camera: |u x e'|
                cx_ = uy * e[2] - uz * e[1]
                cy_ = uz * e[0] - ux * e[2]
                cz_ = ux * e[1] - uy * e[0]
                xi_d = math.sqrt(cx_ * cx_ + cy_ * cy_ + cz_ * cz_)
            p_down = px * down[0] + py * down[1] + pz * down[2]
            q_down = qx * down[0] + qy * down[1] + qz * down[2]
            if (a >= 0.0 and c >= 0.0 and p_down > horizon_margin and q_down > horizon_margin
                    and eta > 0.0):
                delta = eta / p_down
                # p'_r ~ b e' + delta p, seen on the same arc; u is beyond it iff c b > delta a.
                rx, ry, rz = b * e[0] + delta * px, b * e[1] + delta * py, b * e[2] + delta * pz
                rl = math.sqrt(rx * rx + ry * ry + rz * rz)
                vx = uy * rz - uz * ry
                vy = uz * rx - ux * rz
                vz = ux * ry - uy * rx
                dev = math.sqrt(vx * vx + vy * vy + vz * vz) / rl
                side = c * b - delta * a
                if side > 0.0:  # triangulates under the road
                    xi_h = max(dev - lambda_h, 0.0)
                elif side < 0.0:  # above the road
                    lp = lambda_p
                    if adaptive:
                        wx = ry * pz - rz * py
                        wy = rz * px - rx * pz
                        wz = rx * py - ry * px
                        lp = lambda_p_ratio * math.sqrt(wx * wx + wy * wy + wz * wz) / rl
                    xi_p = max(dev - lp, 0.0)
        if with_arc:  # r1^T w: into the current camera's frame
            for j in range(3):
                arc[i, j] = r1[0, j] * wx + r1[1, j] * wy + r1[2, j] * wz
        out[0, i] = xi_e
        out[1, i] = xi_d
        out[2, i] = xi_h
        out[3, i] = xi_p
        out[4, i] = (weights[0] * xi_e + weights[1] * xi_d + weights[2] * xi_h
                     + weights[3] * xi_p) * inv_mu
        valid[i] = True
