"""Turn a pytest-benchmark JSON file into the markdown tables of docs/performance.md.

Usage: python benchmarks/report.py .benchmarks/latest.json
Every ratio is against a peer measured in the same run (PEERS).
"""

from __future__ import annotations

import json
import platform
import sys

import pandas as pd

#: group -> the benchmark (by name prefix) every other row of the group is compared with.
PEERS = {
    "unproject-640x480": "test_cv2_fisheye_undistortPoints_bare",
    "project-640x480": "test_cv2_fisheye_projectPoints",
    "engine-12k": "test_naive_loop_12k[math]",
    "engine-307k": "test_naive_loop_307k[math]",
    "render-640x480": "test_render_peer_farneback",
    "eval-4-sequences": "test_eval_process_pool",
}


def _peer(group: str) -> str | None:
    if group.startswith("detect-"):
        return "test_detect_stage[flow_alone"
    if group.startswith("street-"):
        return "test_detect_street_pair[flow_alone"
    return PEERS.get(group)


#: The targets the speed issue set, each beside its peer from the same run:
#: (target, benchmark, peer benchmark or None, the measured quantity, its limit, at most?).
TARGETS = (
    ("KB unprojection at most bare cv2.fisheye.undistortPoints' time",
     "test_fisheyemotion_unproject[kannala_brandt]", "test_cv2_fisheye_undistortPoints_bare",
     "ratio", 1.0, True),
    ("defaults' non-flow work <= 3 ms, after a real flow call (DIS ultrafast, 1 thread)",
     "test_detect_stage[default_after_flow-dis-ultrafast-1t]",
     "test_detect_stage[flow_alone-dis-ultrafast-1t]", "ms", 3.0, True),
    ("defaults' non-flow work <= 5 ms (the cluttered-streets issue's budget)",
     "test_detect_stage[default_after_flow-farneback-1t]",
     "test_detect_stage[flow_alone-farneback-1t]", "ms", 5.0, True),
    ("the same on a cluttered street's pair with regions (Farneback, 1 thread)",
     "test_detect_street_pair[default_after_flow-farneback]",
     "test_detect_street_pair[flow_alone-farneback]", "ms", 5.0, True),
    ("defaults' non-flow work <= 3 ms in a stream (apply(), DIS ultrafast, 1 thread: the prior, "
     "the warp and everything after the flow method's call)",
     "test_stream_640x480[apply-dis-ultrafast-1t-given]", None, "ms:non_flow_ms", 3.0, True),
    ("defaults' non-flow work <= 5 ms in a stream (apply(), Farneback, 1 thread)",
     "test_stream_640x480[apply-farneback-1t-given]", None, "ms:non_flow_ms", 5.0, True),
    ("DIS ultrafast defaults >= 150 fps on one core (stream, apply())",
     "test_stream_640x480[apply-dis-ultrafast-1t-given]", None, "fps", 150.0, False),
    ("DIS ultrafast defaults >= 150 fps with stream() on both cores (OpenCV 1 thread)",
     "test_stream_640x480[stream-dis-ultrafast-1t-given]", None, "fps", 150.0, False),
    ("pose from the images <= 5 ms per frame pair", "test_pose_estimation[pose_from_images]",
     "test_pose_estimation[peer_farneback]", "ms", 5.0, True),
    ("evaluation on Dask at least as fast as the local pool (timed alternately)",
     "test_eval_dask_interleaved_with_pool", None, "x:ratio", 1.0, True),
    ("import fisheyemotion <= 0.3 s (a new process)", "test_first_result[warm]", None,
     "s:import_s", 0.3, True),
    ("first detect() <= 0.5 s after the import, numba cache warm (peer: numba's own start, "
     "import and one cached kernel)", "test_first_result[warm]", "test_numba_floor",
     "s:first_s", 0.5, True),
    ("first detect() <= 2 s after the import, numba cache cold (peer: without the warm-up)",
     "test_first_result[cold]", "test_first_result[cold-no-warmup]", "s:first_s", 2.0, True),
)


def targets(df: pd.DataFrame) -> pd.DataFrame:
    """Each of :data:`TARGETS` with its measurement, its peer's and whether it is met."""
    by_name = df.set_index("name")
    rows = []
    for text, name, peer, unit, limit, at_most in TARGETS:
        if name not in by_name.index:
            continue
        ms = float(by_name.loc[name, "median_ms"])
        peer_ms = float(by_name.loc[peer, "median_ms"]) if peer in by_name.index else float("nan")
        if unit == "ratio":
            value = ms / peer_ms
        elif unit == "fps":
            value = json.loads(by_name.loc[name, "extra"]).get("fps", float("nan"))
        elif ":" in unit:  # "unit:key": a figure the benchmark measured itself (extra_info)
            unit, key = unit.split(":")
            value = json.loads(by_name.loc[name, "extra"]).get(key, float("nan"))
            if unit == "s" and peer in by_name.index:  # a new process's seconds, both
                peer_ms = 1000 * json.loads(by_name.loc[peer, "extra"]).get(key, float("nan"))
        else:
            value = ms
        met = value <= limit if at_most else value >= limit
        rows.append({"target": text, "measured": f"{value:.3g} {unit}",
                     "peer ms": f"{peer_ms:.3g}", "met": "yes" if met else "no"})
    return pd.DataFrame(rows)


def main(path: str) -> None:
    with open(path) as fh:
        doc = json.load(fh)
    rows = []
    for b in doc["benchmarks"]:
        extra = b.get("extra_info", {})
        med = b["stats"]["median"]
        row = {"group": b["group"], "name": b["name"], "median_ms": med * 1e3}
        if "rays" in extra:
            row["Mrays_per_s"] = extra["rays"] / med / 1e6
        if "frames" in extra:
            row["ms_per_frame"] = med * 1e3 / extra["frames"]
        row["extra"] = json.dumps({k: v for k, v in extra.items() if k not in ("rays", "frames")})
        rows.append(row)
    df = pd.DataFrame(rows)
    df["x_peer_time"] = float("nan")
    for group in df.group.unique():
        peer = _peer(group)
        sel = df.group == group
        ref = df[sel & df.name.str.startswith(peer)].median_ms if peer else []
        if len(ref):
            df.loc[sel, "x_peer_time"] = df[sel].median_ms / ref.iloc[0]
    cpu = doc["machine_info"].get("cpu", {}).get("brand_raw", platform.processor())
    print(f"Machine: {cpu}, {doc['machine_info'].get('cpu', {}).get('count', '?')} cores, "
          f"Python {doc['machine_info']['python_version']}, {doc['datetime']}\n")
    print(df.sort_values(["group", "name"]).to_markdown(index=False, floatfmt=".3g"))
    goals = targets(df)
    if len(goals):
        print("\nTargets (cv2 threads as in each benchmark's name or extra_info):\n")
        print(goals.to_markdown(index=False))


if __name__ == "__main__":
    main(sys.argv[1])
