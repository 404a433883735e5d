"""Turn a pytest-benchmark JSON file into the markdown table of docs/performance.md.

Usage: python benchmarks/report.py .benchmarks/latest.json
Each row's ratio is against the peer named in PEERS, measured in the same run.
"""

from __future__ import annotations

import json
import platform
import sys

import pandas as pd

PEERS = {"unproject-640x480": "test_cv2_fisheye_undistortPoints"}


def main(path: str) -> None:
    doc = json.load(open(path))
    rows = []
    for b in doc["benchmarks"]:
        rows.append({"group": b["group"], "name": b["name"], "median_ms": b["stats"]["median"] * 1e3,
                     "extra": json.dumps(b.get("extra_info", {}))})
    df = pd.DataFrame(rows)
    for group, peer in PEERS.items():
        sel = df.group == group
        ref = df[sel & (df.name == peer)].median_ms
        if len(ref):
            df.loc[sel, "x_vs_peer"] = df[sel].median_ms / ref.iloc[0]
    print(f"Machine: {doc['machine_info'].get('cpu', {}).get('brand_raw', platform.processor())}, "
          f"Python {doc['machine_info']['python_version']}, {doc['datetime']}\n")
    print(df.to_markdown(index=False, floatfmt=".3g"))


if __name__ == "__main__":
    main(sys.argv[1])
