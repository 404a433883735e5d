"""Scenario specs (``data/scenarios/*.yaml``): ego trajectory, camera mounting, scene, objects.

Frames
------
World: x east, y north, z up; the road is ``z = 0``. Vehicle: ISO 8855 (x forward, y left, z up,
origin on the ground). Camera: OpenCV (x right, y down, z forward).

Format (every field but ``name`` has a default)::

    name: crossing
    description: pedestrians and a car crossing ahead
    fps: 15
    frames: 30
    ego: {speed_kmh: 20, yaw_rate_deg_s: 0, start: [0, -1.75], heading_deg: 0}
    camera: {position: [2.0, 0.0, 1.0], pitch_deg: 12, yaw_deg: 0, roll_deg: 0}
    road: {lanes: 2, lane_width: 3.5, verge_width: 4.0}
    static:            # boxes that never move (buildings, parked cars, poles)
      - {kind: building, center: [20, 12], size: [15, 6, 8], yaw_deg: 0, texture: brick}
    objects:           # boxes with constant velocity (moving: speed > 0)
      - {id: 1, kind: pedestrian, category: crossing, start: [10, -6], heading_deg: 90,
         speed_kmh: 5, size: [0.5, 0.6, 1.75], texture: camera}

``center``/``start`` are world ``(x, y)`` of the box's footprint centre; ``size`` is
``(length, width, height)`` in metres along the box's heading, its left, and up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..calib.transforms import make_transform
from .textures import TEXTURES

CATEGORIES = ("crossing", "overtaking", "preceding", "approaching", "static")
KINDS = ("car", "motorcycle", "pedestrian", "building", "pole", "parked_car", "wall", "box")
SCENARIO_DIR = Path(__file__).resolve().parents[2] / "data" / "scenarios"

# Camera axes in the vehicle frame: cam z -> veh x, cam x -> veh -y, cam y -> veh -z.
CAM_IN_VEHICLE = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


#: Object id of the ego vehicle's own body in ``ids`` maps.
EGO_ID = 65535


@dataclass(frozen=True)
class Ego:
    """Ego trajectory (constant speed and yaw rate) and the vehicle's body, ``(length, width,
    height)`` metres, which extends backwards from just behind the camera (``None``: no body)."""

    speed_kmh: float = 20.0
    yaw_rate_deg_s: float = 0.0
    start: tuple[float, float] = (0.0, -1.75)
    heading_deg: float = 0.0
    body: tuple[float, float, float] | None = (4.4, 1.8, 1.45)

    def world_from_vehicle(self, t: float) -> np.ndarray:
        """Vehicle pose at time ``t`` (constant speed and yaw rate)."""
        v = self.speed_kmh / 3.6
        w = math.radians(self.yaw_rate_deg_s)
        h0 = math.radians(self.heading_deg)
        h = h0 + w * t
        if abs(w) < 1e-9:
            dx, dy = v * t * math.cos(h0), v * t * math.sin(h0)
        else:
            dx = v / w * (math.sin(h) - math.sin(h0))
            dy = -v / w * (math.cos(h) - math.cos(h0))
        return make_transform(_rot_z(h), [self.start[0] + dx, self.start[1] + dy, 0.0])


@dataclass(frozen=True)
class Mount:
    position: tuple[float, float, float] = (2.0, 0.0, 1.0)
    pitch_deg: float = 12.0
    yaw_deg: float = 0.0
    roll_deg: float = 0.0

    def vehicle_from_cam(self) -> np.ndarray:
        r = (_rot_z(math.radians(self.yaw_deg)) @ _rot_y(math.radians(self.pitch_deg))
             @ _rot_x(math.radians(self.roll_deg)) @ CAM_IN_VEHICLE)
        return make_transform(r, self.position)


@dataclass(frozen=True)
class RoadSpec:
    lanes: int = 2
    lane_width: float = 3.5
    verge_width: float = 4.0


@dataclass(frozen=True)
class Box:
    """A textured box: static (speed 0) or moving with constant velocity."""

    id: int
    kind: str
    center: tuple[float, float]
    size: tuple[float, float, float]
    yaw_deg: float = 0.0
    speed_kmh: float = 0.0
    texture: str = "gravel"
    category: str = "static"

    @property
    def moving(self) -> bool:
        return self.speed_kmh != 0.0

    def world_from_box(self, t: float) -> np.ndarray:
        """Pose of the box centre (at half height) at time ``t``."""
        yaw = math.radians(self.yaw_deg)
        v = self.speed_kmh / 3.6
        x = self.center[0] + v * t * math.cos(yaw)
        y = self.center[1] + v * t * math.sin(yaw)
        return make_transform(_rot_z(yaw), [x, y, self.size[2] / 2])


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str = ""
    fps: float = 15.0
    frames: int = 30
    ego: Ego = field(default_factory=Ego)
    camera: Mount = field(default_factory=Mount)
    road: RoadSpec = field(default_factory=RoadSpec)
    boxes: tuple[Box, ...] = ()

    def time(self, frame: int) -> float:
        return frame / self.fps

    def world_from_cam(self, frame: int) -> np.ndarray:
        return self.ego.world_from_vehicle(self.time(frame)) @ self.camera.vehicle_from_cam()

    @property
    def ego_static(self) -> bool:
        return self.ego.speed_kmh == 0.0

    def ego_body(self) -> Box | None:
        """The ego vehicle's body as a box in the *vehicle* frame (None if the spec has none)."""
        if self.ego.body is None:
            return None
        length, width, height = self.ego.body
        front = self.camera.position[0] - 0.1
        return Box(id=EGO_ID, kind="box", center=(front - length / 2, 0.0),
                   size=(length, width, height), texture="camera")


# ---- parsing with errors that name the field -------------------------------------------------

class _Reader:
    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, field_: str, expected: str) -> ValueError:
        return ValueError(f"{self.source}: {field_}: {expected}")

    def mapping(self, value: Any, field_: str) -> dict:
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise self.fail(field_, f"expected a mapping, got {type(value).__name__}")
        return value

    def known(self, d: dict, allowed: tuple[str, ...], field_: str) -> None:
        extra = sorted(set(d) - set(allowed))
        if extra:
            raise self.fail(f"{field_}.{extra[0]}" if field_ else extra[0],
                            f"unknown field; expected one of {', '.join(allowed)}")

    def number(self, d: dict, key: str, field_: str, default: float | None = None, *,
               lo: float = -math.inf, hi: float = math.inf, positive: bool = False) -> float:
        name = f"{field_}.{key}" if field_ else key
        if key not in d:
            if default is None:
                raise self.fail(name, "missing")
            return default
        v = d[key]
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise self.fail(name, f"expected a finite number, got {v!r}")
        if positive and v <= 0:
            raise self.fail(name, f"expected > 0, got {v!r}")
        if not lo <= v <= hi:
            raise self.fail(name, f"expected a value in [{lo}, {hi}], got {v!r}")
        return float(v)

    def vector(self, d: dict, key: str, field_: str, n: int, default=None, *, positive=False):
        name = f"{field_}.{key}" if field_ else key
        if key not in d:
            if default is None:
                raise self.fail(name, "missing")
            return tuple(default)
        v = d[key]
        if not isinstance(v, list | tuple) or len(v) != n or not all(
                isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
                for x in v):
            raise self.fail(name, f"expected a list of {n} finite numbers, got {v!r}")
        if positive and min(v) <= 0:
            raise self.fail(name, f"expected positive numbers, got {v!r}")
        return tuple(float(x) for x in v)

    def choice(self, d: dict, key: str, field_: str, options: tuple[str, ...], default: str):
        name = f"{field_}.{key}" if field_ else key
        v = d.get(key, default)
        if v not in options:
            raise self.fail(name, f"expected one of {', '.join(options)}, got {v!r}")
        return v


def parse_scenario(doc: Any, source: str = "<scenario>") -> Scenario:
    """Validate a parsed YAML document into a :class:`Scenario` (ValueError naming the field)."""
    r = _Reader(source)
    d = r.mapping(doc, "(top level)")
    r.known(d, ("name", "description", "fps", "frames", "ego", "camera", "road", "static",
                "objects"), "")
    name = d.get("name")
    if not isinstance(name, str) or not name:
        raise r.fail("name", f"expected a non-empty string, got {name!r}")
    frames = d.get("frames", 30)
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 2:
        raise r.fail("frames", f"expected an integer >= 2, got {frames!r}")
    e = r.mapping(d.get("ego"), "ego")
    r.known(e, ("speed_kmh", "yaw_rate_deg_s", "start", "heading_deg", "body"), "ego")
    body = e.get("body", Ego.body)
    ego = Ego(speed_kmh=r.number(e, "speed_kmh", "ego", 20.0, lo=0, hi=200),
              yaw_rate_deg_s=r.number(e, "yaw_rate_deg_s", "ego", 0.0, lo=-90, hi=90),
              start=r.vector(e, "start", "ego", 2, (0.0, -1.75)),
              heading_deg=r.number(e, "heading_deg", "ego", 0.0),
              body=None if body is None else r.vector(e, "body", "ego", 3, Ego.body, positive=True))
    c = r.mapping(d.get("camera"), "camera")
    r.known(c, ("position", "pitch_deg", "yaw_deg", "roll_deg"), "camera")
    mount = Mount(position=r.vector(c, "position", "camera", 3, (2.0, 0.0, 1.0)),
                  pitch_deg=r.number(c, "pitch_deg", "camera", 12.0, lo=-90, hi=90),
                  yaw_deg=r.number(c, "yaw_deg", "camera", 0.0, lo=-180, hi=180),
                  roll_deg=r.number(c, "roll_deg", "camera", 0.0, lo=-90, hi=90))
    if mount.position[2] <= 0:
        raise r.fail("camera.position", f"expected a camera above the road (z > 0), got {mount.position}")
    rd = r.mapping(d.get("road"), "road")
    r.known(rd, ("lanes", "lane_width", "verge_width"), "road")
    lanes = rd.get("lanes", 2)
    if isinstance(lanes, bool) or not isinstance(lanes, int) or lanes < 1:
        raise r.fail("road.lanes", f"expected an integer >= 1, got {lanes!r}")
    road = RoadSpec(lanes=lanes, lane_width=r.number(rd, "lane_width", "road", 3.5, positive=True),
                    verge_width=r.number(rd, "verge_width", "road", 4.0, lo=0))
    boxes: list[Box] = []
    for section in ("static", "objects"):
        items = d.get(section, []) or []
        if not isinstance(items, list):
            raise r.fail(section, f"expected a list, got {type(items).__name__}")
        for i, item in enumerate(items):
            f = f"{section}[{i}]"
            b = r.mapping(item, f)
            moving = section == "objects"
            r.known(b, ("id", "kind", "category", "center", "start", "size", "yaw_deg",
                        "heading_deg", "speed_kmh", "texture"), f)
            kind = r.choice(b, "kind", f, KINDS, "car" if moving else "box")
            where = "start" if moving else "center"
            bid = b.get("id", len(boxes) + 1)
            if isinstance(bid, bool) or not isinstance(bid, int) or not 1 <= bid < 65535:
                raise r.fail(f"{f}.id", f"expected an integer in [1, 65534], got {bid!r}")
            if any(x.id == bid for x in boxes):
                raise r.fail(f"{f}.id", f"duplicate id {bid}")
            boxes.append(Box(
                id=bid, kind=kind,
                center=r.vector(b, where, f, 2),
                size=r.vector(b, "size", f, 3, _DEFAULT_SIZES[kind], positive=True),
                yaw_deg=r.number(b, "heading_deg" if moving else "yaw_deg", f, 0.0),
                speed_kmh=r.number(b, "speed_kmh", f, 0.0, lo=0, hi=300) if moving else 0.0,
                texture=r.choice(b, "texture", f, tuple(TEXTURES), _DEFAULT_TEXTURES[kind]),
                category=r.choice(b, "category", f, CATEGORIES, "static") if moving else "static",
            ))
    return Scenario(name=name, description=str(d.get("description", "")),
                    fps=r.number(d, "fps", "", 15.0, positive=True, hi=1000), frames=frames,
                    ego=ego, camera=mount, road=road, boxes=tuple(boxes))


_DEFAULT_SIZES = {"car": (4.2, 1.8, 1.5), "parked_car": (4.2, 1.8, 1.5), "motorcycle": (2.0, 0.8, 1.4),
                  "pedestrian": (0.5, 0.6, 1.75), "building": (15.0, 8.0, 8.0), "pole": (0.2, 0.2, 3.0),
                  "wall": (10.0, 0.3, 1.5), "box": (1.0, 1.0, 1.0)}
_DEFAULT_TEXTURES = {"car": "coffee", "parked_car": "chelsea", "motorcycle": "rocket",
                     "pedestrian": "astronaut", "building": "brick", "pole": "camera",
                     "wall": "brick", "box": "gravel"}


def load_scenario(name_or_path: str | Path) -> Scenario:
    """A bundled scenario by name (``data/scenarios/NAME.yaml``) or a YAML file."""
    path = Path(name_or_path)
    if not path.suffix and not path.exists():
        path = SCENARIO_DIR / f"{name_or_path}.yaml"
    if not path.is_file():
        raise ValueError(f"scenario: no bundled scenario or file {str(name_or_path)!r}; "
                         f"bundled: {', '.join(list_scenarios())}")
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML: {str(exc).splitlines()[0]}") from None
    return parse_scenario(doc, str(path))


def list_scenarios() -> list[str]:
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.yaml"))
