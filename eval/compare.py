"""The same scenarios through several camera models, side by side."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from fisheyemotion.calib.fit import fit_model
from matplotlib.figure import Figure

from fisheyemotion import calib, synth
from fisheyemotion.params import Params

from .evaluate import evaluate
from .metrics import table2
from .report import _png


def round_trip_error(camera: calib.CameraModel) -> float:
    """Largest pixel -> ray -> pixel error over the camera's valid pixels."""
    rays, valid = camera.pixel_rays()
    back, ok = camera.project(rays[valid])
    grid = calib.pixel_grid(camera.width, camera.height)[valid]
    return float(np.abs(back[ok] - grid[ok]).max()) if ok.any() else float("nan")


def fit_table(cameras: list[tuple[str, calib.CameraModel]]) -> pd.DataFrame:
    """Every model among the cameras fitted to every camera: RMS pixel error of the fit (a model
    fitted to a camera of its own kind is the sanity check: ~0)."""
    rows = []
    models = list(dict.fromkeys(cam.name for _, cam in cameras))
    for ref_name, ref in cameras:
        for model in models:
            try:
                fitted, rms = fit_model(ref, model)
            except ValueError as exc:  # a pair that cannot be fitted: said, not fatal
                rows.append({"reference": ref_name, "fitted_model": model, "rms_px": np.nan,
                             "reference_fov_deg": ref.fov_deg, "fitted_fov_deg": np.nan,
                             "note": str(exc)})
                continue
            rows.append({"reference": ref_name, "fitted_model": model, "rms_px": rms,
                         "reference_fov_deg": ref.fov_deg, "fitted_fov_deg": fitted.fov_deg,
                         "note": ""})
    return pd.DataFrame(rows)


def compare(cameras: list[tuple[str, calib.CameraModel]], scenarios: list[str], out: Path, *,
            params: Params | None = None, frames: int = 10, workers: int | None = None,
            progress: bool = True) -> Path:
    """Render ``scenarios`` through each camera, evaluate, and write ``compare.md``/``.html``."""
    params = Params() if params is None else params
    out.mkdir(parents=True, exist_ok=True)
    rows, per_model = [], {}
    for name, cam in cameras:
        seqs = []
        for sc_name in scenarios:
            sc = synth.load_scenario(sc_name)
            seqs.append(synth.write_sequence(out / "sequences" / name / sc_name, cam, sc,
                                             frames=frames, flow=False, progress=progress))
        results = evaluate(seqs, params, workers=workers, progress=progress)
        objs = pd.concat([r.objects for r in results if len(r.objects)], ignore_index=True) \
            if any(len(r.objects) for r in results) else pd.DataFrame(columns=["category"])
        frs = pd.concat([r.frames for r in results], ignore_index=True)
        t = table2(objs, frs).assign(camera=name, model=cam.name, fov_deg=round(cam.fov_deg, 1))
        per_model[name] = t
        rows.append(t)
        rows[-1]["round_trip_px"] = round_trip_error(cam)
    table = pd.concat(rows, ignore_index=True)
    table.to_csv(out / "compare.csv", index=False)
    fits = fit_table(cameras)
    fits.to_csv(out / "fits.csv", index=False)
    fig = Figure(figsize=(9, 3.4), layout="constrained")
    ax = fig.subplots()
    pivot = table.pivot(index="category", columns="camera", values="detection_rate")
    pivot.plot.bar(ax=ax, rot=20)
    ax.set_ylabel("detection rate (FP row: FP frames)")
    ax.set_ylim(0, 1)
    png = _png(fig, out / "compare.png")
    md = ["# Camera model comparison", "",
          f"Scenarios: {', '.join(scenarios)}; {frames} frames each; flow {params.flow}.", "",
          table.to_markdown(index=False, floatfmt=".3f"), "",
          "## Fitting one model to another", "",
          "RMS pixel error when the row's fitted model is fitted to the reference camera "
          "(over the reference's valid pixels).", "", fits.to_markdown(index=False, floatfmt=".3f"),
          "", "![compare](compare.png)", ""]
    (out / "compare.md").write_text("\n".join(md))
    import base64

    (out / "compare.html").write_text(
        "<!doctype html><html><head><meta charset='utf-8'><title>compare</title></head><body>"
        "<h1>Camera model comparison</h1>" + table.to_html(index=False) + "<h2>Fits</h2>"
        + fits.to_html(index=False) + f"<p><img src='data:image/png;base64,"
        f"{base64.b64encode(png).decode()}'></p></body></html>")
    return out / "compare.html"
