"""Ray casting of road scenes through any camera model, with exact ground truth.

Every pixel's ray comes from ``camera.unproject`` (the same g(u) the detector uses), is moved
to the world with the camera pose and intersected with the road plane ``z = 0`` and with
textured boxes (one numba pass per ray, ``_raycast.py``). Colour is averaged over
``supersample x supersample`` rays per pixel; the ground truth (ids, range, flow) is exact at
pixel centres.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ..calib.base import CameraModel, pixel_grid
from . import _raycast
from .scenario import EGO_ID, Box, Scenario
from .textures import TEXTURES, packed

_ROAD_TEXEL = 0.005
_BOX_TEXEL = 0.01
_MARK_WIDTH = 0.15
_DASH, _GAP = 3.0, 6.0
# Brightness per face: local +x, -x, +y, -y, +z (top), -z
_FACE_SHADE = np.array([1.0, 0.8, 0.9, 0.7, 1.1, 0.5])
_SKY = np.array([[235, 205, 175], [200, 140, 90]], dtype=np.float64)  # BGR at the horizon, zenith
_NO_HITS = (np.zeros(0), np.zeros((0, 3)), np.zeros(0, np.int64))


@dataclass(frozen=True, eq=False)
class FrameTruth:
    """One rendered frame and its exact ground truth.

    Attributes
    ----------
    index : int
    image : ndarray of uint8, shape (H, W, 3)
        BGR; black outside the camera's valid region.
    ids : ndarray of uint16, shape (H, W)
        Box id at each pixel centre; 0 for road, sky and invalid pixels; ``EGO_ID`` (65535) for
        the ego vehicle's own body.
    moving : ndarray of uint8, shape (H, W)
        255 where a moving box is seen.
    range : ndarray of float32, shape (H, W)
        Distance from the camera centre to the surface hit (inf for sky, NaN outside the camera).
    flow : ndarray of float32, shape (H, W, 2) or None
        Exact flow from the previous frame's pixels to this frame (None for frame 0); NaN where
        the surface point leaves the camera's domain.
    pose : ndarray, shape (4, 4)
        ``world_from_cam``.
    """

    index: int
    image: NDArray[np.uint8]
    ids: NDArray[np.uint16]
    moving: NDArray[np.uint8]
    range: NDArray[np.float32]
    flow: NDArray[np.float32] | None
    pose: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Hits:
    """Nearest intersection per ray: ``obj`` (-1 sky, 0 road, i + 1 for ``boxes[i]``), distance
    ``t``, the hit point in the object's frame (world for road, direction for sky), the face, and
    each box's world rotation at the time of the cast."""

    obj: NDArray[np.int64]
    t: NDArray[np.float64]
    local: NDArray[np.float64]
    face: NDArray[np.int64]
    rotations: tuple[NDArray[np.float64], ...] = ()


class Renderer:
    """Renders the frames of a scenario through a camera.

    Parameters
    ----------
    camera : CameraModel
    scenario : Scenario
    supersample : int, default 2
        Rays per pixel side for the colour image (>= 1; at least 2 keeps flow free of aliasing).
    noise_sigma : float, default 0
        Standard deviation of Gaussian sensor noise (grey levels).
    blur_sigma : float, default 0
        Gaussian blur (pixels) before noise.
    seed : int, default 0
        Seed of the sensor noise.
    """

    def __init__(self, camera: CameraModel, scenario: Scenario, *, supersample: int = 2,
                 noise_sigma: float = 0.0, blur_sigma: float = 0.0, seed: int = 0) -> None:
        if isinstance(supersample, bool) or not isinstance(supersample, int) or not 1 <= supersample <= 8:
            raise ValueError(f"supersample: expected an integer in [1, 8], got {supersample!r}")
        for name, value in (("noise_sigma", noise_sigma), ("blur_sigma", blur_sigma)):
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not np.isfinite(value) or value < 0:
                raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")
        self.camera, self.scenario = camera, scenario
        self.ss, self.noise_sigma, self.blur_sigma, self.seed = supersample, noise_sigma, blur_sigma, seed
        w, h = camera.width, camera.height
        self._rays, self._valid = camera.pixel_rays()
        offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
        ou, ov = np.meshgrid(offsets, offsets)
        sub = pixel_grid(w, h)[:, :, None, :] + np.stack([ou.ravel(), ov.ravel()], -1)
        sub_rays, sub_valid = camera.unproject(sub)  # (H, W, ss*ss, 3)
        self._sub_rays = np.ascontiguousarray(sub_rays[sub_valid])
        self._sub_pixel = np.flatnonzero(sub_valid) // (supersample * supersample)
        self._centre_rays = np.ascontiguousarray(self._rays[self._valid])
        self._centre_pixels = pixel_grid(w, h)[self._valid]
        # Angle between neighbouring samples, at the image centre (1 / focal length).
        fx, fy, _, _ = camera._affine()
        self._sample_angle = 1.0 / (max(fx, fy) * supersample)
        self._prev_hits: tuple[int, Hits] | None = None
        boxes = self._all_boxes
        self._box_texture = np.array([TEXTURES.index(b.texture) for b in boxes], np.int64)
        spec = scenario.road
        self._half_road = spec.lanes * spec.lane_width / 2
        lines = [(-self._half_road, False), (self._half_road, False)] + [
            (-self._half_road + k * spec.lane_width, True) for k in range(1, spec.lanes)]
        self._lines = np.array([o for o, _ in lines], float)
        self._dashed = np.array([d for _, d in lines], bool)
        self._body_sub = self._body_hits(self._sub_rays)
        self._body_centre = self._body_hits(self._centre_rays)

    # ---- geometry -----------------------------------------------------------------------
    def _boxes_at(self, t: float) -> list[tuple[Box, np.ndarray]]:
        out = [(b, b.world_from_box(t)) for b in self.scenario.boxes]
        body = self.scenario.ego_body()
        if body is not None:  # rigidly attached to the vehicle
            out.append((body, self.scenario.ego.world_from_vehicle(t) @ body.world_from_box(0.0)))
        return out

    @property
    def _all_boxes(self) -> list[Box]:
        body = self.scenario.ego_body()
        return list(self.scenario.boxes) + ([body] if body is not None else [])

    def intersect(self, origin: NDArray, dirs: NDArray, time: float, *,
                  body: tuple[NDArray, NDArray, NDArray] | None = None) -> Hits:
        """Nearest hits of world rays ``dirs`` (N, 3) from ``origin`` at scenario time ``time``.

        ``body``: precomputed ``(t, local, face)`` of the ego vehicle's body for these rays
        (rigid with the camera, so the same in every frame); cast here when None.
        """
        return self._cast(origin, np.eye(3), dirs, self._boxes_at(time), body=body)

    def _cast(self, origin: NDArray, rot: NDArray, rays: NDArray,
              boxes: list[tuple[Box, NDArray]], *,
              body: tuple[NDArray, NDArray, NDArray] | None) -> Hits:
        """Hits of rays ``rot @ rays[i]`` from ``origin`` with the road and ``boxes`` (box,
        world_from_box); ``body`` stands for the last box when given."""
        n = len(rays)
        obj = np.empty(n, np.int64)
        t = np.empty(n)
        local = np.empty((n, 3))
        face = np.empty(n, np.int64)
        n_cast = len(boxes) - (body is not None)
        _raycast.cast(np.asarray(origin, float), np.ascontiguousarray(rot),
                      np.ascontiguousarray(rays, dtype=float), *self._box_arrays(origin, boxes),
                      n_cast, *self._precomputed(body), obj, t, local, face)
        return Hits(obj, t, local, face, tuple(p[:3, :3] for _, p in boxes))

    def _box_arrays(self, origin: NDArray, boxes: list[tuple[Box, NDArray]]):
        """Per box: world rotation, the origin in the box frame, half sizes, and the cone (unit
        axis and cosine of the half-angle) its bounding sphere subtends from ``origin``."""
        k = len(boxes)
        rots, centres = self._box_poses(boxes)
        box_origin = np.empty((k, 3))
        halves = np.empty((k, 3))
        axis_dir = np.zeros((k, 3))
        cone_cos = np.full(k, -2.0)  # origin inside the sphere: never culled
        for j, (box, _) in enumerate(boxes):
            offset = centres[j] - origin
            box_origin[j] = -offset @ rots[j]
            halves[j] = np.array(box.size, float) / 2
            dist = float(np.linalg.norm(offset))
            radius = float(np.linalg.norm(halves[j]))
            if dist > radius:
                axis_dir[j] = offset / dist
                cone_cos[j] = np.sqrt(dist**2 - radius**2) / dist
        return rots, box_origin, halves, axis_dir, cone_cos

    def _precomputed(self, body):
        """``(pre_t, pre_obj, pre_local, pre_face)`` kernel arguments for the body's hits."""
        pre_t, pre_local, pre_face = _NO_HITS if body is None else body
        return pre_t, len(self.scenario.boxes) + 1, pre_local, pre_face

    @staticmethod
    def _box_poses(boxes: list[tuple[Box, NDArray]]) -> tuple[NDArray, NDArray]:
        """World rotations ``(k, 3, 3)`` and centres ``(k, 3)`` of ``boxes``."""
        rots = np.array([p[:3, :3] for _, p in boxes], float).reshape(-1, 3, 3)
        return rots, np.array([p[:3, 3] for _, p in boxes], float).reshape(-1, 3)

    def _body_hits(self, rays_cam: NDArray) -> tuple[NDArray, NDArray, NDArray] | None:
        """The ego body's hits for camera-frame rays (the same in every frame)."""
        body = self.scenario.ego_body()
        if body is None:
            return None
        vehicle_from_cam = self.scenario.camera.vehicle_from_cam()
        pose = body.world_from_box(0.0)  # in the vehicle frame
        hits = self._cast(vehicle_from_cam[:3, 3], vehicle_from_cam[:3, :3], rays_cam,
                          [(body, pose)], body=None)
        t = np.where(hits.obj == 1, hits.t, np.inf)
        return t, hits.local, hits.face

    # ---- frames -------------------------------------------------------------------------
    def hits(self, index: int) -> Hits:
        """Ground-truth hits at the pixel centres of frame ``index`` (valid pixels only)."""
        if self._prev_hits is not None and self._prev_hits[0] == index:
            return self._prev_hits[1]
        pose = self.scenario.world_from_cam(index)
        return self._cast(pose[:3, 3], pose[:3, :3], self._centre_rays,
                          self._boxes_at(self.scenario.time(index)), body=self._body_centre)

    def roi(self) -> NDArray[np.uint8]:
        """255 where the camera sees the scene, 0 where it sees its own vehicle or nothing."""
        ids = np.zeros((self.camera.height, self.camera.width), np.uint16)
        hits = self.hits(0)
        box_ids = np.array([0] + [b.id for b in self._all_boxes], dtype=np.uint16)
        ids[self._valid] = box_ids[np.maximum(hits.obj, 0)]
        return np.where(self._valid & (ids != EGO_ID), 255, 0).astype(np.uint8)

    def render(self, index: int) -> FrameTruth:
        """Frame ``index`` with its ground truth (flow from frame ``index - 1``)."""
        cam, sc = self.camera, self.scenario
        h, w = cam.height, cam.width
        pose = sc.world_from_cam(index)
        time = sc.time(index)
        # Colour: mean of the supersamples (samples outside the camera's domain count as black).
        boxes = self._boxes_at(time)
        acc = np.zeros((h * w, 3))
        hits = self._cast(pose[:3, 3], pose[:3, :3], self._sub_rays, boxes, body=self._body_sub)
        _raycast.shade(
            np.ascontiguousarray(pose[:3, :3]), self._sub_rays, hits.obj, hits.t, hits.local,
            hits.face, self._sub_pixel, 1.0 / self.ss**2, np.array(hits.rotations),
            self._box_texture, _FACE_SHADE, _SKY, TEXTURES.index("gravel"), TEXTURES.index("grass"),
            _ROAD_TEXEL, _BOX_TEXEL, self._half_road, _MARK_WIDTH, self._lines, self._dashed,
            _DASH, _DASH + _GAP, self._sample_angle, *packed(), acc)
        image = acc.reshape(h, w, 3).astype(np.float32)
        if self.blur_sigma > 0:
            image = cv2.GaussianBlur(image, (0, 0), self.blur_sigma)
        if self.noise_sigma > 0:
            rng = np.random.default_rng([self.seed, index])
            image = image + rng.normal(0, self.noise_sigma, image.shape).astype(np.float32)
        image = np.clip(np.rint(image), 0, 255).astype(np.uint8)
        image[~self._valid] = 0
        # Ground truth at pixel centres.
        hits = self.hits(index)
        ids = np.zeros((h, w), np.uint16)
        box_ids = np.array([0] + [b.id for b in self._all_boxes], dtype=np.uint16)
        ids[self._valid] = box_ids[np.maximum(hits.obj, 0)]
        moving_ids = [b.id for b in sc.boxes if b.moving]
        moving = np.where(np.isin(ids, moving_ids) & (ids > 0), 255, 0).astype(np.uint8)
        rng_map = np.full((h, w), np.nan, np.float32)
        rng_map[self._valid] = hits.t
        flow = None if index == 0 else self.flow(index)
        self._prev_hits = (index, hits)
        return FrameTruth(index, image, ids, moving, rng_map, flow, pose)

    def flow(self, index: int, *, gap: int = 1) -> NDArray[np.float32]:
        """Exact flow ``(H, W, 2)`` from frame ``index - gap`` to frame ``index``: where each
        pixel's surface point of the earlier frame is seen in frame ``index`` (NaN where it leaves
        the camera's domain; occlusion is not tested)."""
        if not isinstance(gap, int) or not 1 <= gap <= index:
            raise ValueError(f"gap: expected an integer in [1, index={index}], got {gap!r}")
        sc, cam = self.scenario, self.camera
        prev = self.hits(index - gap)
        pose1 = sc.world_from_cam(index)
        boxes = self._boxes_at(sc.time(index))
        rots, centres = self._box_poses(boxes)
        rays = np.empty_like(prev.local)
        _raycast.seen_from(prev.obj, prev.local, rots, centres, pose1[:3, 3],
                           np.ascontiguousarray(pose1[:3, :3]), rays)
        pixels, ok = cam.project(rays)
        flow = np.full((cam.height, cam.width, 2), np.nan, np.float32)
        flow[self._valid] = np.where(ok[:, None], pixels - self._centre_pixels, np.nan)
        return flow


def render_frames(camera: CameraModel, scenario: Scenario, *, frames: int | None = None,
                  **kwargs) -> list[FrameTruth]:
    """All frames (or the first ``frames``) of a scenario, in order."""
    r = Renderer(camera, scenario, **kwargs)
    n = scenario.frames if frames is None else min(frames, scenario.frames)
    return [r.render(k) for k in range(n)]
