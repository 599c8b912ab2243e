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
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path


def wall(cmd: list[str]) -> float:
    return timed(cmd)[0]


def timed(cmd: list[str]) -> tuple[float, float]:
    """Wall time and CPU time (user + system) of a child process, s."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return t, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


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
            ours, theirs = [], []
            for _ in range(args.repeats):
                ours.append(timed([*cli, "-q", "localisation", bag, "--out", str(tmp / "ws"), "--no-figures", "--force"]))
                if evo:
                    theirs.append(timed([evo, sub, bag, "/mocap/pose", "/icp/pose", "-a", "--sync_method", "interpolation",
                                         "--t_offset", str(-truth["delay"]), "--no_warnings"]))
            figs = wall([*cli, "-q", "localisation", bag, "--out", str(tmp / "ws"), "--force"])
            med = [statistics.median(v) for v in zip(*ours)]
            med_evo = [statistics.median(v) for v in zip(*theirs)] if theirs else [float("nan")] * 2
            rows.append((name, *med, *med_evo, figs))
            print(f"{name}: ours {ours}, evo {theirs}, ours with figures {figs}", file=sys.stderr)
        print(f"\nMeasured {date.today().isoformat()} on {platform.machine()}, {os.cpu_count()} cores, Python "
              f"{platform.python_version()}, load average {os.getloadavg()[0]:.1f}; {args.repeats} alternating repeats, "
              "medians of the whole process (wall and CPU = user + system).\n")
        print("| bag | ours wall (s) | evo wall (s) | wall ratio ours / evo | ours CPU (s) | evo CPU (s) | CPU ratio | ours with figures, wall (s) |")
        print("|---|---|---|---|---|---|---|---|")
        for name, ow, oc, ew, ec, f in rows:
            print(f"| {name} ({truth['duration']:.0f} s run) | {ow:.2f} | {ew:.2f} | {ow / ew:.2f} | {oc:.2f} | {ec:.2f} | "
                  f"{oc / ec:.2f} | {f:.2f} |")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
