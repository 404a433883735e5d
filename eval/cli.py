"""``fisheyemotion eval``, ``compare`` and ``demo``: registered into the core CLI by entry point."""

from __future__ import annotations

import argparse
import math
import os
import shlex
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from fisheyemotion import calib, synth
from fisheyemotion.cli import REPO_DATA, CliError, calib_files, calibration_table, integer_type
from fisheyemotion.outputs import atomic_folder
from fisheyemotion.params import FLOW_METHODS, Params

from .evaluate import EXACT, evaluate, sequence_paths
from .pose_sources import Perturbation
from .report import table2_by_flow, write_report

DEMO_CAMERA = "front_kb_640x480.yaml"
#: The cluttered streets are rendered with both a Kannala-Brandt and a double-sphere camera, at
#: their own length (48 frames).
STREET_CAMERAS = {"kb": "front_kb_640x480.yaml", "ds": "front_ds_640x480.yaml"}


def _params(args: argparse.Namespace) -> Params:
    """``--params FILE``, or ``--params paper`` for the paper's pipeline exactly."""
    value = getattr(args, "params", None)
    if value == "paper":
        return Params.paper()
    return Params.load(value) if value else Params()


def _height(text: str) -> float | str:
    if text == "scene":
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected metres or 'scene', got {text!r}") from None


_seed = integer_type(0, "an integer")
_workers = integer_type(1, "a number of processes")


def _non_negative(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return value


def _flows(text: str) -> list[str]:
    """``--flow``: flow methods, and ``exact`` for the rendered scenes' exact flow."""
    flows = [f.strip() for f in text.split(",") if f.strip()]
    known = (*FLOW_METHODS, EXACT)
    bad = [f for f in flows if f not in known]
    if bad or not flows:
        raise CliError(f"--flow: expected a comma-separated list of {', '.join(known)}; got "
                       f"{text!r}")
    return list(dict.fromkeys(flows))


def run_eval(paths: list[Path], params: Params, flows: list[str], out: Path, *,
             workers: int | None, scheduler: str | None, progress: bool,
             commands: list[str] | None = None, title: str = "fisheyemotion evaluation",
             real_data: Path | None = None, **options):
    results = []
    for flow in flows:  # the exact flow (rendered scenes only) replaces the flow method
        exact = flow == EXACT
        results += evaluate(paths, params if exact else params.replace(flow=flow),
                            workers=workers, scheduler=scheduler, progress=progress,
                            exact_flow=exact, **options)
    real = pairs = None
    if real_data is not None and (real_data / "real").is_dir():
        from .real import run_pairs, run_real

        real, pairs = run_real(real_data), run_pairs(real_data)
    report = write_report(results, out, params, commands=commands, title=title, real=real,
                          pairs=pairs)
    return results, report


def cmd_eval(args: argparse.Namespace) -> int:
    paths = sequence_paths(args.seq_dirs)
    params = _params(args)
    if args.pose_refinement:
        params = params.replace(pose_refinement=args.pose_refinement)
    final = Path(args.out)
    with atomic_folder(final, overwrite=args.overwrite) as out:
        results, report = run_eval(paths, params, _flows(args.flow), out,
                                   workers=args.workers, scheduler=args.scheduler,
                                   progress=not args.quiet,
                                   commands=["fisheyemotion " + shlex.join(sys.argv[1:])],
                                   world=args.world, road=args.road,
                                   camera_height=args.camera_height, poses=args.poses,
                                   noise=Perturbation(rotation_deg=args.noise_rotation,
                                                      translation=args.noise_translation,
                                                      time_offset_s=args.noise_time_offset,
                                                      seed=args.noise_seed))
        if args.additions:
            _write_additions(paths, args, out)
    _print_table2(results)
    print(f"report: {final / report.name}")
    return 0


def _write_additions(paths: list[Path], args: argparse.Namespace, out: Path) -> None:
    from .evaluate import additions_table

    flows = [f for f in _flows(args.flow) if f != EXACT]  # the table has its exact-flow row
    table, scenes = additions_table(paths, flows or [Params().flow], workers=args.workers,
                                    progress=not args.quiet, by_sequence=True)
    table.to_csv(out / "additions.csv", index=False)
    scenes.to_csv(out / "additions_by_sequence.csv", index=False)
    md = out / "report.md"
    per_scene = "".join(
        f"\n### {label} per sequence\n\n"
        + scenes.pivot_table(index=["flow", "variant"], columns="sequence", values=column,
                             sort=False).to_markdown(floatfmt=".2f") + "\n"
        for column, label in (("detection", "Detection rate"),
                              ("fp_frames", "False-positive frames")))
    md.write_text(md.read_text() + "\n## The additions beyond the paper, each alone and all "
                  "together\n\n" + table.to_markdown(index=False, floatfmt=".2f") + "\n"
                  + per_scene + "\nEvery figure per sequence (detection, coverage, "
                  "false-positive frames and static pixels, IoU): additions_by_sequence.csv\n")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.2f}"))


def _print_table2(results) -> None:
    wide = table2_by_flow(results)
    with pd.option_context("display.float_format", lambda v: f"{v:.2f}", "display.width", 160):
        print(wide.to_string(index=False))


def cmd_compare(args: argparse.Namespace) -> int:
    from .compare import compare

    cameras = [(Path(c).stem, calib.load(c)) for c in args.calib]
    if len(cameras) < 2:
        raise CliError("--calib: give at least two calibration files to compare")
    scenarios = args.scenarios.split(",") if args.scenarios else synth.list_scenarios()
    final = Path(args.out)
    with atomic_folder(final, overwrite=args.overwrite) as tmp:
        out = compare(cameras, scenarios, tmp, params=_params(args), frames=args.frames,
                      workers=args.workers, progress=not args.quiet)
    print(f"report: {final / out.name}")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    data = Path(args.data)
    print(f"Bundled calibrations in {data / 'calib'}:")
    print(calibration_table(calib_files(data)).to_string(index=False))
    out = Path(args.out)
    camera = calib.load(data / "calib" / DEMO_CAMERA)
    names = args.scenarios.split(",") if args.scenarios else synth.list_scenarios()
    jobs = []
    for name in names:
        spec = data / "scenarios" / f"{name}.yaml"
        if name.startswith("street"):
            jobs += [(calib.load(data / "calib" / cam_file), spec,
                      out / "sequences" / f"{name}_{suffix}", None)
                     for suffix, cam_file in STREET_CAMERAS.items()]
        else:
            jobs.append((camera, spec, out / "sequences" / name, args.frames))
    with ProcessPoolExecutor(max_workers=args.workers or os.cpu_count() or 1) as pool:
        seqs = list(tqdm(pool.map(_render, jobs), total=len(jobs), desc="synth",
                         disable=args.quiet, leave=False))
    print(f"Rendered {len(seqs)} sequences into {out / 'sequences'}: open-road scenarios x "
          f"{args.frames} frames with {DEMO_CAMERA}, cluttered streets at their own length with "
          f"{', '.join(STREET_CAMERAS.values())}")
    with atomic_folder(out / "report", overwrite=True) as tmp:  # the demo's own folder
        results, report = run_eval(
            seqs, Params(), _flows(args.flow), tmp, workers=args.workers, scheduler=None,
            progress=not args.quiet, title="fisheyemotion demo: bundled scenarios",
            real_data=data,
            commands=[f"fisheyemotion demo --frames {args.frames} --flow {args.flow}"])
    _print_table2(results)
    print(f"Report: {(out / 'report' / report.name).resolve()}")
    return 0


def _render(job) -> Path:
    camera, spec, out, frames = job
    return synth.write_sequence(out, camera, synth.load_scenario(spec), frames=frames, flow=False,
                                progress=False)


def register(sub: argparse._SubParsersAction) -> None:
    """Add this package's commands to the ``fisheyemotion`` parser."""
    p = sub.add_parser("eval", help="evaluate detection on sequence folders and write a report")
    p.add_argument("seq_dirs", nargs="+", metavar="SEQ_DIR",
                   help="sequence folders, or folders holding them")
    p.add_argument("--params", help="YAML/JSON file of Params, or 'paper' for the paper's "
                   "pipeline (default: the defaults)")
    p.add_argument("--flow", default="farneback",
                   help="flow methods, comma-separated: farneback, dis, and exact for the "
                        "rendered scenes' exact flow (default: %(default)s)")
    p.add_argument("--out", required=True, help="report folder (written whole at the end)")
    p.add_argument("--overwrite", action="store_true", help="replace a non-empty --out")
    p.add_argument("--workers", type=_workers, help="local processes (default: CPU count)")
    p.add_argument("--scheduler", help="Dask distributed scheduler address, tcp://host:port "
                   "(default: none, a local process pool)")
    p.add_argument("--world", choices=("scene", "first_camera", "raised"), default="scene",
                   help="give the detector the poses in this world frame: the scene's (z up, "
                   "road z = 0), the first camera's, or z up with the road at -1.7 m and turned "
                   "30 deg (default: %(default)s)")
    p.add_argument("--road", choices=("given", "auto"), default="given",
                   help="the scene's road in that frame, or estimated from the stream "
                   "(default: %(default)s)")
    p.add_argument("--camera-height", type=_height, metavar="METRES",
                   help="with --road auto: the camera's height above the road, when known, or "
                        "'scene' for each sequence's own (default: unknown)")
    p.add_argument("--poses", choices=("true", "estimated", "perturbed"), default="true",
                   help="the poses the detector is given: the true ones, estimated from the "
                        "images (speed from the true poses), or the true ones with noise "
                        "(--noise-*) (default: %(default)s)")
    p.add_argument("--noise-seed", type=_seed, default=0, metavar="N",
                   help="with --poses perturbed: the noise's draw (default: %(default)s)")
    p.add_argument("--noise-rotation", type=_non_negative, default=Perturbation.rotation_deg,
                   metavar="DEG", help="with --poses perturbed: each frame's orientation turned "
                   "by this angle about a random axis (default: %(default)s)")
    p.add_argument("--noise-translation", type=_non_negative, default=Perturbation.translation,
                   metavar="SHARE", help="with --poses perturbed: each frame's position moved "
                   "by this share of the frame-to-frame step in a random direction (default: "
                   "%(default)s)")
    p.add_argument("--noise-time-offset", type=_non_negative,
                   default=Perturbation.time_offset_s, metavar="SECONDS",
                   help="with --poses perturbed: the poses are this much late (default: "
                   "%(default)s)")
    p.add_argument("--pose-refinement", choices=("off", "on", "auto"),
                   help="refine the given poses' rotation on the images first (default: the "
                        "one in --params, off)")
    p.add_argument("--additions", action="store_true",
                   help="also evaluate the paper's pipeline with each addition alone and all "
                        "together (additions.csv, a section of report.md), with the flow "
                        "methods of --flow (the default one if it names only exact)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_eval)

    p = sub.add_parser("compare", help="the same scenarios through several camera models")
    p.add_argument("--calib", action="append", required=True, help="calibration file (repeat)")
    p.add_argument("--scenarios", help="comma-separated bundled scenario names (default: all)")
    p.add_argument("--frames", type=int, default=10,
                   help="frames rendered per scenario and camera (default: %(default)s)")
    p.add_argument("--params", help="YAML/JSON file of Params, or 'paper' (default: the "
                   "defaults)")
    p.add_argument("--out", required=True, help="report folder (written whole at the end)")
    p.add_argument("--overwrite", action="store_true", help="replace a non-empty --out")
    p.add_argument("--workers", type=_workers, help="local processes (default: CPU count)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser("demo", help="render the bundled scenarios, detect, write a report")
    p.add_argument("--data", default=str(REPO_DATA),
                   help="folder of calib/, scenarios/ and real/ (default: the bundled data/)")
    p.add_argument("--out", default="data/generated/demo",
                   help="output folder: sequences/ and report/, replaced on each run "
                        "(default: %(default)s)")
    p.add_argument("--frames", type=int, default=16,
                   help="frames per open-road scenario; the streets keep their own 48 "
                        "(default: %(default)s)")
    p.add_argument("--scenarios", help="comma-separated scenario names (default: all)")
    p.add_argument("--flow", default="farneback,dis,exact",
                   help="flow methods, comma-separated: farneback, dis, and exact for the "
                        "rendered scenes' exact flow (default: %(default)s)")
    p.add_argument("--workers", type=_workers, help="local processes (default: CPU count)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_demo)
