"""Command line: ``fisheyemotion {detect,synth,calib}`` (+ ``eval``, ``compare``, ``demo`` from
:mod:`fisheyemotion.eval`).

Errors are one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from collections import deque
from collections.abc import Callable, Sequence
from importlib.metadata import entry_points
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
from tqdm import tqdm

from . import calib
from .detector import MotionDetector
from .params import Params
from .road import Road

REPO_DATA = Path(__file__).resolve().parents[1] / "data"


class CliError(ValueError):
    """A user error reported as one line."""


class _SourceError(ValueError):
    """A frame the input could not give (raised by the input, naming it)."""


# ---- calibrations ---------------------------------------------------------------------------

def calibration_table(paths: Sequence[Path]) -> pd.DataFrame:
    """One row per camera of each calibration file: file, camera, model, size, FOV."""
    rows = []
    for path in paths:
        rig = calib.load_rig(path)
        for name, cam in zip(rig.names, rig.cameras, strict=True):
            rows.append({
                "file": path.name, "camera": name, "model": cam.name,
                "size": f"{cam.width}x{cam.height}", "fov_deg": round(cam.fov_deg, 1),
                "theta_max_deg": round(float(np.degrees(cam.theta_max)), 1),
                "valid_px_%": round(100 * float(cam.valid_pixel_mask().mean()), 1),
            })
    return pd.DataFrame(rows)


def calib_files(data: Path) -> list[Path]:
    """Calibration files in ``data/calib``."""
    return sorted(p for p in (data / "calib").iterdir()
                  if p.suffix in {".yaml", ".yml", ".json", ".xml", ".txt"})


def cmd_calib(args: argparse.Namespace) -> int:
    """Every file is read; the ones that fail are reported after the table (exit code 2)."""
    good, failed = [], []
    for name in args.files:
        try:
            calibration_table([Path(name)])
            good.append(Path(name))
        except ValueError as exc:
            failed.append(str(exc))
    if good:
        print(calibration_table(good).to_string(index=False))
    for message in failed:
        print(f"fisheyemotion calib: error: {message}", file=sys.stderr)
    return 2 if failed else 0


# ---- detect ---------------------------------------------------------------------------------

def _parse_road(text: str | None) -> Road | str:
    """``--road``: ``auto`` (estimate, the default), ``none``, ``z0`` (the plane z = 0) or
    ``nx,ny,nz,offset``."""
    if not text or text == "auto":
        return "auto"
    if text == "none":
        return Road.unknown()
    if text == "z0":
        return Road()
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        raise CliError(f"--road: expected auto, none, z0 or 'nx,ny,nz,offset', got {text!r}") from None
    if len(v) != 4:
        raise CliError(f"--road: expected 4 numbers 'nx,ny,nz,offset', got {len(v)}")
    try:
        return Road(normal=tuple(v[:3]), offset=v[3])
    except ValueError as exc:
        raise CliError(f"--road: {exc}") from None


def _poses_file(source: Path, given: str | None) -> Path | None:
    """``--poses``, else ``poses.txt`` or a single ``poses*.csv`` in the input folder."""
    if given:
        return Path(given)
    if not source.is_dir():
        return None
    candidates = [source / "poses.txt"] if (source / "poses.txt").is_file() else sorted(
        source.glob("poses*.csv"))
    return candidates[0] if len(candidates) == 1 else None


def run_detect(frames, camera: calib.CameraModel, matcher, out: Path, *,
               road: Road | str, params: Params, write_video: bool, progress: bool = True,
               roi: np.ndarray | None = None, camera_height: float | None = None,
               fps: float | None = None, show: bool = False) -> pd.DataFrame:
    """Detect over a whole input into ``out`` (a fresh folder): an annotated frame for every
    input frame (video at the input's rate, or PNGs named like the frames), likelihood maps and
    masks (npz), ``regions.csv`` and ``regions.jsonl`` with each region's frame, time, bearing
    and ground distance, and ``poses.txt`` (the poses used, TUM). ``show``: each annotated
    frame also in a window (q or Esc closes it; detection goes on)."""
    from .draw import annotate
    from .outputs import region_records
    from .overlap import BackgroundWriter, read_ahead
    from .poses import write_tum

    (out / "likelihood").mkdir()
    if not write_video:
        (out / "annotated").mkdir()
    detector = MotionDetector(camera, road, params, roi=roi, camera_height=camera_height)
    video = _VideoSink(out / "annotated.mp4", fps) if write_video else None
    rows, stamps, used = [], [], []
    total = len(frames) or None
    fed: deque = deque()  # (frame, name, its pose's stamp) of the frames given to the stream

    def items():
        source = iter(tqdm(read_ahead(frames), desc="detect", total=total, disable=not progress,
                           leave=False))
        while True:
            try:
                frame = next(source)
            except StopIteration:
                return
            except ValueError as exc:  # a frame that cannot be read: its message names it
                raise _SourceError(str(exc)) from None
            name = Path(frame.name).stem if frame.name else f"{frame.index:06d}"
            fed.append((frame, name, None))
            stamp, pose = (None, None) if matcher is None else matcher(
                frame.index, frame.name, frame.stamp)
            fed[-1] = (frame, name, stamp)
            yield frame.image, pose

    # Frames are read ahead and outputs written behind in two threads; the detector's stream
    # decides one frame pair's result while it measures the next pair's flow.
    results = detector.stream(items())
    with BackgroundWriter() as background:
        while True:
            try:
                result = next(results)
            except StopIteration:
                break
            except _SourceError as exc:
                raise CliError(str(exc)) from None
            except ValueError as exc:  # raised while the newest frame was taken in
                frame, name, _ = fed[-1]
                raise CliError(f"frame {frame.index} ({name}): {exc}") from None
            frame, name, stamp = fed.popleft()
            pose = detector.last_pose
            stamp = frame.stamp if frame.stamp is not None else stamp
            stamps.append(frame.index if stamp is None else stamp)
            used.append(pose)
            if result is None:  # the frame gap is filling: nothing detected yet
                shown = frame.image if frame.image.ndim == 3 else cv2.cvtColor(
                    frame.image, cv2.COLOR_GRAY2BGR)
                mask = np.zeros(frame.image.shape[:2], np.uint8)
                likelihood = np.zeros(frame.image.shape[:2], np.float32)
            else:
                shown, mask, likelihood = (annotate(frame.image, result), result.mask,
                                           result.likelihood)
                for rec in region_records(result.regions, camera, pose, detector.road):
                    rows.append({"frame": frame.index, "name": frame.name, "timestamp": stamp,
                                 **rec})
            background.submit(np.savez_compressed, out / "likelihood" / f"{name}.npz",
                              likelihood=likelihood, mask=mask)
            if video is not None:
                background.submit(video.write, shown)
            else:
                background.submit(cv2.imwrite, str(out / "annotated" / f"{name}.png"), shown)
            if show:
                show = _show(shown)
        if video is not None:  # after the last frame's write: jobs run in order
            background.submit(video.close)
    columns = ["frame", "name", "timestamp", "label", "x", "y", "w", "h", "area",
               "mean_likelihood", "u", "v", "azimuth_deg", "elevation_deg", "ground_distance_m"]
    table = pd.DataFrame(rows, columns=columns)
    table.to_csv(out / "regions.csv", index=False)
    table.to_json(out / "regions.jsonl", orient="records", lines=True)
    if used:
        write_tum(out / "poses.txt", stamps, used)
    road_note = (f"road: normal {np.round(detector.road.up, 4).tolist()}, offset "
                 f"{detector.road.offset:.3f} m" if detector.road.known else "road: none found")
    (out / "road.txt").write_text(road_note + "\n")
    return table


class _VideoSink:
    """An mp4 at ``path`` opened on the first frame written (its size is the frame's)."""

    def __init__(self, path: Path, fps: float | None) -> None:
        self.path, self.fps, self.writer = path, fps or 15.0, None

    def write(self, image: np.ndarray) -> None:
        if self.writer is None:
            self.writer = cv2.VideoWriter(str(self.path), cv2.VideoWriter_fourcc(*"mp4v"),
                                          self.fps, (image.shape[1], image.shape[0]))
        self.writer.write(image)

    def close(self) -> None:
        if self.writer is not None:
            self.writer.release()


WINDOW = "fisheyemotion detect"


def _check_gui() -> None:
    """``--show`` needs an OpenCV built with a GUI; the headless wheel this package installs
    has none."""
    if re.search(r"GUI:\s+NONE", cv2.getBuildInformation()):
        raise CliError("--show: this OpenCV build has no GUI (opencv-python-headless, which "
                       "fisheyemotion installs); install opencv-python in its place to show "
                       "windows, or watch the annotated output afterwards")


def _show(image: np.ndarray) -> bool:
    """Show ``image``; False once the user closed the window with q or Esc."""
    try:
        cv2.imshow(WINDOW, image)
        key = cv2.waitKey(1) & 0xFF
    except cv2.error as exc:
        raise CliError(f"--show: cannot open a window ({str(exc).strip().splitlines()[-1]})") \
            from None
    if key in (ord("q"), 27):
        cv2.destroyWindow(WINDOW)
        return False
    return True


def cmd_detect(args: argparse.Namespace) -> int:
    from .inputs import open_source
    from .outputs import atomic_folder
    from .poses import PoseMatcher, read_poses

    if args.show:
        _check_gui()
    source = Path(args.input)
    frames = open_source(source, image_topic=args.image_topic)
    is_bag = hasattr(frames, "trajectory")
    is_sequence = (source / "frames").is_dir()
    circle = None  # the image circle of a nominal camera (--calib circle[:FOV])
    fov = _circle_fov(args.calib) if args.calib else None
    if fov is not None:
        camera, circle = _nominal_camera(frames, args.calib, fov)
        extrinsic = None
    elif args.calib:
        rig = calib.load_rig(args.calib)
        camera, extrinsic = rig[args.camera], rig.extrinsic(args.camera)
    elif is_bag:
        camera, extrinsic = frames.camera(args.info_topic), None
    elif is_sequence:
        camera, extrinsic = calib.load(source / "calib.yaml"), None
    else:
        raise CliError("--calib is required unless INPUT is a sequence folder or a bag with "
                       "CameraInfo")
    if is_bag and (args.pose_topic or args.pose_frame):
        times = [f.stamp for f in frames]
        trajectory = frames.trajectory(pose_topic=args.pose_topic, pose_frame=args.pose_frame,
                                       world_frame=args.world_frame, times=np.array(times))
    else:
        poses_path = _poses_file(source, args.poses)
        trajectory = None if poses_path is None else read_poses(poses_path)
    if trajectory is None:
        if args.camera_height is not None and args.road == "auto":
            scale = (f"each step scaled by the road {args.camera_height:g} m below the camera; "
                     "the road estimated")
            road = "auto"
        else:
            scale = "scale unknown without --camera-height: no road terms"
            road = Road.unknown()
        print("fisheyemotion detect: no poses given or found in the input: estimating them from "
              f"the images ({scale}); written to OUT/poses.txt", file=sys.stderr)
        matcher = None
    else:
        if args.poses_of == "rig":
            if extrinsic is None:
                raise CliError("--poses-of rig: the calibration file has no extrinsic for "
                               f"camera {args.camera!r}")
            trajectory = trajectory.compose(extrinsic)
        matcher = PoseMatcher(trajectory, args.match, max_gap=args.max_dt,
                              frames=len(frames) or None)
        road = _parse_road(args.road)
        if isinstance(road, Road):
            from .ground import check_road

            for note in check_road(road, trajectory.poses, "--road", warn=False):
                print(f"fisheyemotion detect: warning: {note}", file=sys.stderr)
    params = _detect_params(args, camera)
    count = len(frames)
    if count == 1:
        raise CliError(f"{source}: one frame; detection needs two or more")
    if 2 <= count <= params.frame_gap:  # a frame pair, or a short clip: compare what there is
        print(f"fisheyemotion detect: the input has {count} frames: frame gap {count - 1} "
              f"instead of {params.frame_gap}", file=sys.stderr)
        params = params.replace(frame_gap=count - 1)
    roi_path = Path(args.roi) if args.roi else (source / "roi.png" if is_sequence else None)
    roi = None
    if roi_path is not None and (args.roi or roi_path.exists()):
        roi = cv2.imread(str(roi_path), cv2.IMREAD_GRAYSCALE)
        if roi is None:
            raise CliError(f"{roi_path}: cannot be read as an image")
    if circle is not None:  # the image's own pixels only (and the given ROI's)
        inside = circle.mask(camera.width, camera.height)
        if roi is not None and roi.shape != inside.shape:
            raise CliError(f"--roi: expected a {camera.width}x{camera.height} mask (the "
                           f"frames' size), got {roi.shape[1]}x{roi.shape[0]}")
        roi = inside if roi is None else np.where(roi > 0, inside, 0).astype(np.uint8)
    write_video = not source.is_dir() or is_bag
    with atomic_folder(Path(args.out), overwrite=args.overwrite) as tmp:
        if circle is not None:  # the guess, for the user to read, reuse or replace
            calib.save_opencv(camera, tmp / "calib.yaml")
            cv2.imwrite(str(tmp / "roi.png"), roi)
        table = run_detect(frames, camera, matcher, tmp, road=road, params=params,
                           write_video=write_video, progress=not args.quiet, roi=roi,
                           camera_height=args.camera_height, fps=frames.fps, show=args.show)
        road_note = (tmp / "road.txt").read_text().strip()
    print(f"{len(table)} regions in {table['frame'].nunique()} frames; {road_note}; "
          f"written to {args.out}")
    return 0


def _circle_fov(text: str) -> float | None:
    """The field of view of ``--calib circle[:FOV]`` (degrees; 180 by default), or None where
    ``text`` names a calibration file."""
    if text != "circle" and not text.startswith("circle:"):
        return None
    if text == "circle":
        return 180.0
    try:
        fov = float(text.split(":", 1)[1])
    except ValueError:
        fov = math.nan
    if not (math.isfinite(fov) and 0 < fov < 360):
        raise CliError(f"--calib: expected circle or circle:FOV with FOV in degrees in (0, 360), "
                       f"got {text!r}")
    return fov


def _nominal_camera(frames, text: str, fov: float
                    ) -> tuple[calib.CameraModel, calib.ImageCircle]:
    """``--calib circle[:FOV]`` (``text``, ``fov`` degrees): the nominal equidistant camera of
    the first frame's image circle (:mod:`fisheyemotion.calib.circle`), said on stderr."""
    source = iter(frames)
    try:
        first = next(source)
    except StopIteration:
        raise CliError("--calib circle: the input has no frames") from None
    except ValueError as exc:
        raise CliError(str(exc)) from None
    finally:
        if hasattr(source, "close"):  # a video's or a bag's reader: released now
            source.close()
    try:
        circle = calib.find_image_circle(first.image)
    except ValueError as exc:
        raise CliError(f"--calib {text}: frame {first.index}: {exc}") from None
    h, w = first.image.shape[:2]
    camera = calib.nominal_camera(circle, w, h, fov_deg=fov)
    print(f"fisheyemotion detect: --calib {text}: a nominal equidistant camera, the image circle "
          f"of frame {first.index} (centre {circle.cx:.1f}, {circle.cy:.1f}, radius "
          f"{circle.radius:.1f} px) {fov:g} deg across: f = {camera.fx:.2f} px; a guess of the "
          "lens, not a calibration (written to OUT/calib.yaml, the circle to OUT/roi.png)",
          file=sys.stderr)
    return camera, circle


def integer_type(minimum: int, what: str) -> Callable[[str], int]:
    """An argparse type: an integer ``>= minimum`` (``what`` names it in the error)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = minimum - 1
        if value < minimum:
            raise argparse.ArgumentTypeError(f"expected {what} >= {minimum}, got {text!r}")
        return value
    return parse


def _detect_params(args: argparse.Namespace, camera: calib.CameraModel) -> Params:
    """``--params FILE`` or ``paper``; the defaults scaled to the camera's resolution."""
    if args.params == "paper":
        params = Params.paper().for_camera(camera)
    elif args.params:
        params = Params.load(args.params)
    else:
        params = Params().for_camera(camera)
    if args.frame_gap is not None:
        params = params.replace(frame_gap=args.frame_gap)
    return params.replace(flow=args.flow) if args.flow else params


# ---- synth ----------------------------------------------------------------------------------

def cmd_synth(args: argparse.Namespace) -> int:
    from . import synth

    if args.list:
        for name in synth.list_scenarios():
            sc = synth.load_scenario(name)
            print(f"{name:16s} {sc.frames:4d} frames  {sc.description}")
        return 0
    if not args.scenario or not args.calib or not args.out:
        raise CliError("--scenario, --calib and --out are required (or --list)")
    scenario = synth.load_scenario(args.scenario)
    camera = calib.load(args.calib, camera=args.camera)
    out = synth.write_sequence(args.out, camera, scenario, frames=args.frames, seed=args.seed,
                               supersample=args.supersample, noise_sigma=args.noise,
                               overwrite=args.overwrite,
                               progress=not args.quiet)
    print(f"wrote {out}")
    return 0


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("fisheyemotion")
    except PackageNotFoundError:
        return "unknown (not installed)"


def _camera_arg(text: str) -> int | str:
    return int(text) if text.isdigit() else text


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fisheyemotion",
        description="Moving-object detection for moving fisheye cameras (spherical constraints, "
                    "Mariotti & Hughes 2019). Errors are one line on stderr and exit code 2.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("detect", help="detect moving objects in a video, image folder, "
                       "sequence folder or ROS bag")
    p.add_argument("input", help="video file, folder of frames, sequence folder, ROS 1 .bag or "
                   "ROS 2 bag folder")
    p.add_argument("--calib", help="calibration file (default: INPUT/calib.yaml of a sequence, "
                   "or the bag's CameraInfo), or circle[:FOV] for a circular fisheye without one: "
                   "a nominal equidistant camera from the first frame's image circle, FOV "
                   "degrees across (default 180)")
    p.add_argument("--camera", type=_camera_arg, default=0,
                   help="camera index or name in --calib (default: %(default)s)")
    p.add_argument("--poses", help="pose file: TUM, KITTI, EuRoC CSV, Aria CSV, MPS CSV (closed "
                   "or open loop), a CSV whose header names tx..qw and a timestamp with its unit, "
                   ".npy or .npz (default: poses.txt or poses*.csv in INPUT; none: estimated from "
                   "the images, scale unknown, written to OUT/poses.txt)")
    p.add_argument("--poses-of", choices=("camera", "rig"), default="camera",
                   help="the poses are of the camera, or of the calibration's reference frame "
                   "(IMU, device, vehicle), composed with the camera's extrinsic "
                   "(default: %(default)s)")
    p.add_argument("--match", choices=("auto", "timestamp", "name", "index"), default="auto",
                   help="pair frames with poses by time (interpolated), frame name, or index "
                   "(default: %(default)s: name when the poses are named, else time when both "
                   "have times, else the frame's number)")
    p.add_argument("--max-dt", type=float, default=0.05,
                   help="seconds a frame may be from the poses around it (default: %(default)s)")
    p.add_argument("--road", default="auto",
                   help="auto (estimate it), none, z0, or 'nx,ny,nz,offset' in the world frame "
                   "(default: %(default)s)")
    p.add_argument("--camera-height", type=float, metavar="METRES",
                   help="the camera's height above the road, when known: checks the estimated "
                        "road and, without poses, gives the estimated steps their length in "
                        "metres (default: unknown)")
    p.add_argument("--params", help="YAML/JSON file of Params, or 'paper' (default: the "
                   "defaults, grid and areas scaled to the camera's resolution)")
    p.add_argument("--roi", help="mask image of pixels to use (default: INPUT/roi.png if present)")
    p.add_argument("--flow", choices=("farneback", "dis"),
                   help="the flow method (default: the one in --params, farneback)")
    p.add_argument("--frame-gap", type=integer_type(1, "a number of frames"), metavar="N",
                   help="compare each frame with the one N frames before (default: the one in "
                        "--params, 3: chosen at 15 fps; about 0.2 s of travel suits other rates)")
    p.add_argument("--image-topic", help="bag: the image topic (default: the only one)")
    p.add_argument("--info-topic", help="bag: the CameraInfo topic (default: the image topic's "
                   "camera_info)")
    p.add_argument("--pose-topic", help="bag: a PoseStamped or Odometry topic (default: none; "
                   "poses from --pose-frame, --poses, or estimated)")
    p.add_argument("--pose-frame", help="bag: the tf frame whose poses to use, from /tf and "
                   "/tf_static (default: none)")
    p.add_argument("--world-frame", help="bag: the tf frame the poses are in (default: the root)")
    p.add_argument("--out", required=True, help="output folder (written whole at the end)")
    p.add_argument("--overwrite", action="store_true", help="replace a non-empty --out")
    p.add_argument("--show", action="store_true",
                   help="show each annotated frame in a window as it is done (needs an OpenCV "
                        "build with a GUI, e.g. opencv-python; q or Esc stops)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_detect)

    p = sub.add_parser("synth", help="render a scenario to a sequence folder")
    p.add_argument("--scenario", help="bundled scenario name or YAML file (required unless "
                   "--list)")
    p.add_argument("--calib", help="calibration file of the camera (required unless --list)")
    p.add_argument("--camera", type=_camera_arg, default=0,
                   help="camera index or name in --calib (default: %(default)s)")
    p.add_argument("--frames", type=int, help="number of frames, at least 2 (default: the "
                   "scenario's)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the sensor noise (default: %(default)s)")
    p.add_argument("--supersample", type=int, default=2,
                   help="rays per pixel along each axis, 1-8 (default: %(default)s)")
    p.add_argument("--noise", type=float, default=0.0,
                   help="sensor noise sigma, grey levels (default: %(default)s)")
    p.add_argument("--out", help="output sequence folder, written whole at the end (required "
                   "unless --list)")
    p.add_argument("--overwrite", action="store_true", help="replace a non-empty --out")
    p.add_argument("--list", action="store_true", help="list the bundled scenarios")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_synth)

    p = sub.add_parser("calib", help="print model, size and FOV of calibration files")
    p.add_argument("files", nargs="+", help="calibration files (every one is read; failures are "
                   "listed after the table)")
    p.set_defaults(func=cmd_calib)

    # Commands of packages built on the core (fisheyemotion.eval: eval, compare, demo) register
    # through entry points, so that the core never imports them.
    for ep in entry_points(group="fisheyemotion.commands"):
        ep.load()(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ValueError, OSError) as exc:
        print(f"fisheyemotion {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
