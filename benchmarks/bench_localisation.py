"""Localisation end to end on a 10-minute synthetic run, side by side with evo_ape (issue 5).

    python benchmarks/bench_localisation.py [--repeats 3] [--laps 4] [--speed 0.105]

Writes the run (motion capture 200 Hz, ICP 10 Hz) as a ROS1 bag and an MCAP file, then times, as
separate processes and alternating so that machine load hits both alike:
- `cobot-analysis localisation BAG --no-figures` (reads the bag, estimates the delay, offset,
  errors, drift, goals, writes the tables and results.md);
- `evo_ape bag|mcap BAG /mocap/pose /icp/pose -a --sync_method interpolation --t_offset -DELAY`
  (reads the bag, associates with the delay given, Umeyama, APE statistics; no delay estimation);
- `cobot-analysis localisation BAG` with figures, for information.
Prints a Markdown table of the median wall times and the ratio ours / evo.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path


def wall(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--laps", type=int, default=4)
    ap.add_argument("--speed", type=float, default=0.105)
    args = ap.parse_args()
    evo = shutil.which("evo_ape")
    cli = [sys.executable, "-m", "cobot_analysis"]
    tmp = Path(tempfile.mkdtemp(prefix="bench-loc-"))
    try:
        t_synth = wall([*cli, "-q", "synth", "localisation", "--out", str(tmp), "--laps", str(args.laps),
                        "--speed", str(args.speed), "--formats", "ros1,mcap"])
        truth = json.loads((tmp / "synth-localisation" / "truth.json").read_text())
        print(f"synthetic run: {truth['duration']:.0f} s, {truth['n_mocap']} mocap + {truth['n_icp']} ICP poses, "
              f"written (ROS1 + MCAP) in {t_synth:.1f} s", file=sys.stderr)
        rows = []
        for name, sub in (("run.bag", "bag"), ("run.mcap", "mcap")):
            bag = str(tmp / "synth-localisation" / name)
            ours, theirs, figs = [], [], []
            for _ in range(args.repeats):
                ours.append(wall([*cli, "-q", "localisation", bag, "--out", str(tmp / "ws"), "--no-figures", "--force"]))
                if evo:
                    theirs.append(wall([evo, sub, bag, "/mocap/pose", "/icp/pose", "-a", "--sync_method", "interpolation",
                                        "--t_offset", str(-truth["delay"]), "--no_warnings"]))
            figs.append(wall([*cli, "-q", "localisation", bag, "--out", str(tmp / "ws"), "--force"]))
            rows.append((name, statistics.median(ours), statistics.median(theirs) if theirs else float("nan"), figs[0]))
            print(f"{name}: ours {ours}, evo {theirs}, ours with figures {figs}", file=sys.stderr)
        print(f"\nMeasured {date.today().isoformat()} on {platform.machine()}, {os.cpu_count()} cores, Python "
              f"{platform.python_version()}; {args.repeats} alternating repeats, median wall time of the whole process.\n")
        print("| bag | cobot-analysis localisation (s) | evo_ape -a (s) | ratio ours / evo | ours with figures (s) |")
        print("|---|---|---|---|---|")
        for name, o, e, f in rows:
            print(f"| {name} ({truth['duration']:.0f} s run) | {o:.2f} | {e:.2f} | {o / e:.2f} | {f:.2f} |")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
