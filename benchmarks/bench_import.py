"""Throughput of `cobot-analysis import` on a synthetic walking study (C3D, 200 Hz, 14 markers).

    python benchmarks/bench_import.py [--subjects 10 --trials 3 --conditions 40] [--study DIR]

Generates the study with ``cobot_analysis.synth.walking.generate`` (unless --study names an
existing one), then times, once each: the per-file C3D read (``io.c3d.read_c3d``, median over the
files, alternating with ``read_c3d(numpy=False)``: the same checks, ezc3d reading the data) and
the whole CLI import (``--jobs 1`` and ``--jobs 2``, wall time in a fresh process).
Prints a Markdown fragment for docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", type=int, default=10)
    ap.add_argument("--trials", type=int, default=3)
    ap.add_argument("--conditions", type=int, default=40)
    ap.add_argument("--study", type=Path, help="existing study directory (with protocol.yaml)")
    args = ap.parse_args()

    from cobot_analysis.design import WALKING_CONDITIONS
    from cobot_analysis.io.c3d import read_c3d

    tmp = Path(tempfile.mkdtemp(prefix="bench_import."))
    if args.study:
        protocol = args.study / "protocol.yaml"
    else:
        from cobot_analysis.synth import walking

        t0 = time.perf_counter()
        protocol = walking.generate(tmp / "study", n_subjects=args.subjects, n_trials=args.trials,
                                    conditions=list(WALKING_CONDITIONS[: args.conditions]), jobs=2)
        print(f"generated in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    files = sorted((protocol.parent / "raw").glob("*.c3d"))
    times, ref_times, frames = [], [], 0
    for f in files:  # alternating: our numpy reader, then ezc3d (the reference) on the same file
        t0 = time.perf_counter()
        raw = read_c3d(f)
        times.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        read_c3d(f, numpy=False)
        ref_times.append(time.perf_counter() - t0)
        frames += raw.xyz.shape[0]
    n_markers = raw.xyz.shape[1]
    walls = {}
    for jobs in (1, 2):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "cobot_analysis", "-q", "import", str(protocol), "--out", str(tmp / f"ws{jobs}"),
                        "--jobs", str(jobs), "--force"], check=True)
        walls[jobs] = time.perf_counter() - t0
    rows = frames * n_markers
    load = os.getloadavg()[0]
    print(f"- {datetime.now(timezone.utc):%Y-%m-%d}, {platform.machine()}, {os.cpu_count()} cores, load average "
          f"{load:.1f} at the end; {len(files)} C3D files, {frames} frames x {n_markers} markers ({rows / 1e6:.1f} M rows).")
    print(f"- `read_c3d` (checks + numpy reader): median {statistics.median(times) * 1000:.2f} ms per file "
          f"({sum(times):.1f} s for all, one process); with ezc3d reading the data (`numpy=False`, alternating): "
          f"{statistics.median(ref_times) * 1000:.2f} ms (ratio {statistics.median(times) / statistics.median(ref_times):.2f}).")
    for jobs, wall in walls.items():
        print(f"- `cobot-analysis import --jobs {jobs}`: {wall:.1f} s wall ({rows / wall / 1e6:.2f} M marker samples/s), "
              "process start and Parquet write included.")


if __name__ == "__main__":
    main()
