"""Per-ray kernels of the renderer (numba): intersect the road plane and boxes, shade the hit.

One ray at a time: :func:`cast` tests a ray against a box only inside the cone its bounding sphere
subtends, then by the slab method in the box frame; :func:`shade` samples a mipmapped texture
chosen by the surface footprint of one sample and accumulates the mean colour of each pixel's
samples in place.

Object codes: -1 sky, 0 road, ``j + 1`` for box ``j``. Faces: ``2 * axis + (0 if the hit is on the
+axis side else 1)`` in the box frame.
"""

from __future__ import annotations

import math

import numba
import numpy as np

SKY, ROAD = -1, 0
# Per-ray helpers take scalars only: passing arrays to a helper (inlined or not) made numba count
# references per array per ray, 7x slower (28 vs 4 ms for 307k rays).
_JIT = dict(cache=True, nogil=True, error_model="numpy")


@numba.njit(**_JIT)
def _fmin(a, b):
    if a != a:
        return b
    if b != b:
        return a
    return min(a, b)


@numba.njit(**_JIT)
def _fmax(a, b):
    if a != a:
        return b
    if b != b:
        return a
    return max(a, b)


@numba.njit(**_JIT)
def cast(origin, rot, rays, rots, box_origin, halves, axis_dir, cone_cos, n_boxes, pre_t, pre_obj,
         pre_local, pre_face, obj, t, local, face):
    """Nearest hits of the camera-frame ``rays`` (N, 3), rotated to the world by ``rot``
    (world_from_cam), from ``origin``: fills ``obj``, ``t``, ``local`` (N, 3) and ``face``.

    ``box_origin[j]``: the ray origin in box ``j``'s frame; ``axis_dir[j]``: unit direction to its
    centre, ``cone_cos[j]``: cosine of the half-angle its bounding sphere subtends (-2 when the
    origin is inside it); boxes ``j >= n_boxes`` are not cast. ``pre_*``: a precomputed hit per
    ray (the ego body, object ``pre_obj``), used when ``pre_t`` is not empty. ``local`` is the
    hit in the box frame, the world point for the road and the direction for the sky.
    """
    ox, oy, oz = origin[0], origin[1], origin[2]
    has_pre = pre_t.shape[0] > 0
    for i in range(rays.shape[0]):
        x, y, z = rays[i, 0], rays[i, 1], rays[i, 2]
        dx = rot[0, 0] * x + rot[0, 1] * y + rot[0, 2] * z
        dy = rot[1, 0] * x + rot[1, 1] * y + rot[1, 2] * z
        dz = rot[2, 0] * x + rot[2, 1] * y + rot[2, 2] * z
        best = np.inf
        obj_i = SKY
        face_i = -1
        lx, ly, lz = dx, dy, dz
        if dz < -1e-12:
            best = -oz / dz
            obj_i = ROAD
        if has_pre:
            pt = pre_t[i]
            if pt < best:
                best = pt
                obj_i = pre_obj
                lx, ly, lz = pre_local[i, 0], pre_local[i, 1], pre_local[i, 2]
                face_i = pre_face[i]
        for j in range(n_boxes):
            if dx * axis_dir[j, 0] + dy * axis_dir[j, 1] + dz * axis_dir[j, 2] <= cone_cos[j]:
                continue
            # Direction in the box frame: d_l = R^T d.
            d0 = rots[j, 0, 0] * dx + rots[j, 1, 0] * dy + rots[j, 2, 0] * dz
            d1 = rots[j, 0, 1] * dx + rots[j, 1, 1] * dy + rots[j, 2, 1] * dz
            d2 = rots[j, 0, 2] * dx + rots[j, 1, 2] * dy + rots[j, 2, 2] * dz
            t_in = -np.inf
            t_out = np.inf
            axis = 0
            for k in range(3):
                dk = d0 if k == 0 else (d1 if k == 1 else d2)
                inv = 1.0 / dk
                o = box_origin[j, k]
                h = halves[j, k]
                t1 = (-h - o) * inv
                t2 = (h - o) * inv
                tn = _fmin(t1, t2)
                tf = _fmax(t1, t2)
                if tn > t_in:  # NaN never wins: argmax with NaN as -inf
                    t_in = tn
                    axis = k
                t_out = _fmin(t_out, tf)
            if t_in <= t_out and t_in > 0.0 and t_in < best:
                best = t_in
                obj_i = j + 1
                lx = box_origin[j, 0] + t_in * d0
                ly = box_origin[j, 1] + t_in * d1
                lz = box_origin[j, 2] + t_in * d2
                pa = lx if axis == 0 else (ly if axis == 1 else lz)
                face_i = 2 * axis + (0 if pa > 0.0 else 1)
        if obj_i == ROAD:
            lx, ly, lz = ox + best * dx, oy + best * dy, oz + best * dz
        obj[i] = obj_i
        t[i] = best
        local[i, 0], local[i, 1], local[i, 2] = lx, ly, lz
        face[i] = face_i


@numba.njit(**_JIT)
def mip_level(footprint, texel, levels):
    """Mipmap level whose texels match ``footprint`` metres (``texel`` metres at level 0)."""
    ratio = footprint / texel
    if not ratio > 1.0:  # also NaN
        return 0
    return min(int(math.floor(math.log2(ratio))), levels - 1)


@numba.njit(**_JIT)
def texel_index(u, v, scale, h, w):
    """Row-major index of the texel at ``(u, v)`` metres in an ``h x w`` tiling of ``scale``
    metres per texel (``v`` up, rows down)."""
    col = int(math.floor(u / scale)) % w
    row = int(math.floor(-v / scale)) % h
    return row * w + col


@numba.njit(**_JIT)
def shade(rot, rays, obj, t, local, face, pixel, weight, rots, box_texture, face_shade, sky,
          road_texture, verge_texture, road_texel, box_texel, half_road, mark_width, lines, dashed,
          dash, period, sample_angle, tex_data, tex_table, tex_levels, image):
    """Add ``weight`` x the colour of every hit (from :func:`cast`) to ``image[pixel[i]]``.

    Textures: nearest texel of the mipmap level matching the sample's footprint on the surface
    (distance x ``sample_angle`` / cos(incidence)), so that far and grazing surfaces are
    prefiltered instead of aliasing. ``tex_table[k, level] = (offset, height, width)`` in the
    packed ``tex_data`` (M, 3); ``tex_levels[k]`` levels per texture.
    """
    for i in range(rays.shape[0]):
        x, y, z = rays[i, 0], rays[i, 1], rays[i, 2]
        dx = rot[0, 0] * x + rot[0, 1] * y + rot[0, 2] * z
        dy = rot[1, 0] * x + rot[1, 1] * y + rot[1, 2] * z
        dz = rot[2, 0] * x + rot[2, 1] * y + rot[2, 2] * z
        o = obj[i]
        if o == SKY:
            el = min(max(dz, 0.0), 1.0)
            b = sky[0, 0] * (1 - el) + sky[1, 0] * el
            g = sky[0, 1] * (1 - el) + sky[1, 1] * el
            r = sky[0, 2] * (1 - el) + sky[1, 2] * el
        else:
            lx, ly, lz = local[i, 0], local[i, 1], local[i, 2]
            gain = 1.0
            if o == ROAD:
                cos_n = dz
                u, v = lx, ly
                k, texel = road_texture, road_texel
                if abs(ly) > half_road + mark_width:
                    k, texel = verge_texture, 2 * road_texel
            else:
                j = o - 1
                f = face[i]
                axis = f // 2
                cos_n = rots[j, 0, axis] * dx + rots[j, 1, axis] * dy + rots[j, 2, axis] * dz
                # Face coordinates: horizontal along the face, vertical up (top: x, y).
                u = (ly if axis == 0 else lx) + 7.3 * j
                v = ly if axis == 2 else lz
                k, texel = box_texture[j], box_texel
                gain = face_shade[f]
            level = mip_level(t[i] * sample_angle / max(abs(cos_n), 0.05), texel, tex_levels[k])
            idx = tex_table[k, level, 0] + texel_index(
                u, v, texel * 2.0**level, tex_table[k, level, 1], tex_table[k, level, 2])
            b, g, r = gain * tex_data[idx, 0], gain * tex_data[idx, 1], gain * tex_data[idx, 2]
            if o == ROAD:
                for m in range(lines.shape[0]):
                    if abs(ly - lines[m]) < mark_width / 2 and (not dashed[m] or lx % period < dash):
                        b, g, r = b * 0.25 + 200.0, g * 0.25 + 200.0, r * 0.25 + 200.0
        p = pixel[i]
        image[p, 0] += weight * b
        image[p, 1] += weight * g
        image[p, 2] += weight * r


@numba.njit(**_JIT)
def seen_from(obj, local, rots, centres, origin, rot, out):
    """Camera-frame directions (N, 3) from ``origin`` (camera ``rot``, world_from_cam) to the
    surface points of earlier hits, after each box moved to pose ``(rots[j], centres[j])``; for the
    sky, the hit's direction rotated into the camera (at infinity only rotation matters)."""
    for i in range(obj.shape[0]):
        o = obj[i]
        lx, ly, lz = local[i, 0], local[i, 1], local[i, 2]
        if o == SKY:
            wx, wy, wz = lx, ly, lz
        elif o == ROAD:
            wx, wy, wz = lx - origin[0], ly - origin[1], lz - origin[2]
        else:
            j = o - 1
            wx = rots[j, 0, 0] * lx + rots[j, 0, 1] * ly + rots[j, 0, 2] * lz + centres[j, 0] - origin[0]
            wy = rots[j, 1, 0] * lx + rots[j, 1, 1] * ly + rots[j, 1, 2] * lz + centres[j, 1] - origin[1]
            wz = rots[j, 2, 0] * lx + rots[j, 2, 1] * ly + rots[j, 2, 2] * lz + centres[j, 2] - origin[2]
        out[i, 0] = rot[0, 0] * wx + rot[1, 0] * wy + rot[2, 0] * wz
        out[i, 1] = rot[0, 1] * wx + rot[1, 1] * wy + rot[2, 1] * wz
        out[i, 2] = rot[0, 2] * wx + rot[1, 2] * wy + rot[2, 2] * wz
