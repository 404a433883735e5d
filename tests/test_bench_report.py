"""benchmarks/report.py's targets table names benchmarks that exist (the benchmarks themselves
run in ``make bench``, not here)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_benchmark_the_targets_table_names_exists():
    """benchmarks/report.py reads its targets by benchmark id: an id that a benchmark's
    parametrisation no longer makes would print NaN (0.8.7's stream ids gained ``-given``)."""
    root = ROOT
    listed = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
         str(root / "benchmarks")], capture_output=True, text=True, cwd=root, check=True).stdout
    ids = {line.split("::")[-1] for line in listed.splitlines() if "::" in line}
    sys.path.insert(0, str(root / "benchmarks"))
    try:
        from report import PEERS, TARGETS
    finally:
        sys.path.pop(0)
    named = {t[1] for t in TARGETS} | {t[2] for t in TARGETS if t[2]} | set(PEERS.values())
    assert named <= ids, sorted(named - ids)
