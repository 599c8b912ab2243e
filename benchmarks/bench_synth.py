"""Time the full synthetic studies (``synth walking``, ``synth pairs``) through the CLI.

    python benchmarks/bench_synth.py [--jobs 2] [--keep DIR]

Prints a Markdown table (wall time, files, bytes, truth rows) for docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import tempfile
import time
from datetime import date
from pathlib import Path

import pyarrow.parquet as pq

from cobot_analysis.cli import run


def measure(out: Path, command: str, jobs: int) -> dict:
    t0 = time.perf_counter()
    code = run(["--quiet", "synth", command, "--out", str(out), "--jobs", str(jobs), "--force"])
    wall = time.perf_counter() - t0
    if code != 0:
        raise SystemExit(f"synth {command} failed with exit code {code}")
    stage = out / f"synth-{command}"
    c3d = list((stage / "raw").glob("*.c3d"))
    return {"command": f"synth {command}", "wall_s": wall, "files": len(c3d),
            "mb": sum(f.stat().st_size for f in stage.rglob("*") if f.is_file()) / 1e6,
            "truth_rows": pq.ParquetFile(stage / "truth.parquet").metadata.num_rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--keep", type=Path, help="write the studies here instead of a temporary directory")
    args = parser.parse_args()
    out = args.keep or Path(tempfile.mkdtemp(prefix="bench-synth-"))
    load = os.getloadavg()[0]
    try:
        rows = [measure(out, "walking", args.jobs), measure(out, "pairs", args.jobs)]
    finally:
        if args.keep is None:
            shutil.rmtree(out, ignore_errors=True)
    print(f"{date.today()}, {platform.machine()}, {os.cpu_count()} cores, --jobs {args.jobs}, "
          f"load average before the run {load:.1f}\n")
    print("| command | wall time (s) | C3D files | output (MB) | truth rows |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| `{r['command']}` (default design) | {r['wall_s']:.1f} | {r['files']} | {r['mb']:.0f} | {r['truth_rows']:,} |")


if __name__ == "__main__":
    main()
