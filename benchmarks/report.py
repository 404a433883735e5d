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
    return PEERS.get(group)


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


if __name__ == "__main__":
    main(sys.argv[1])
