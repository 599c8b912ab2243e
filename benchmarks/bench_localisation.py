"""Localisation end to end on a 10-minute synthetic run, side by side with evo_ape (issues 5, 22).

    python benchmarks/bench_localisation.py [--pairs 7] [--laps 4] [--speed 0.105] [--figures] [--against DIR]

Both commands run with Python's bytecode cache on and once each before the pairs (warm-up).
Writes the run (`synth localisation`: motion capture 200 Hz, ICP 10 Hz) as a ROS1 bag and an MCAP
file, then runs, as separate processes, alternating in pairs so that the machine's load hits both
alike (the order inside a pair alternates too):
- ours: `cobot-analysis localisation BAG --no-figures` (reads the bag, estimates the delay, offset,
  errors, drift, goals, writes the tables and results.md);
- evo: `evo_ape bag|mcap BAG /mocap/pose /icp/pose -a --sync_method interpolation --t_offset -DELAY`
  (reads the bag, associates with the delay given, Umeyama, APE statistics; no delay estimation).
Prints, per bag, the median of the per-pair wall-time ratios ours / evo (the figure to quote:
robust to load that changes between pairs) and of the CPU-time ratios (user + system: the steadier
figure on a shared machine), the median wall and CPU times, each command's peak
resident memory (max over the pairs, from wait4) and their ratio, and the load average before
and after. ``--against DIR`` (a source tree of another version, e.g. ``git archive main | tar -x -C DIR``)
runs that version's command in every pair too, in rotating order: a row per version, and the medians of
the per-pair ratios this version / DIR's (wall and CPU).
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
from datetime import datetime, timezone
from pathlib import Path


# Both commands run as installed programs run: Python's bytecode cache on. (With PYTHONDONTWRITEBYTECODE
# set, as in some shells, our package would be compiled from source at every run while evo's
# site-packages come with their bytecode.) One run of each command before the pairs fills the caches.
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def run(cmd: list[str], env: dict[str, str] = ENV) -> tuple[float, float, float]:
    """Wall time (s), CPU time (user + system, s) and peak resident memory (MiB) of one process, run in the
    root directory (``python -m`` puts the working directory first on the path: the version run is PYTHONPATH's)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, cwd="/")
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{err}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=7, help="alternating (ours, evo) pairs per bag")
    ap.add_argument("--laps", type=int, default=4)
    ap.add_argument("--speed", type=float, default=0.105)
    ap.add_argument("--figures", action="store_true", help="also time ours with figures once (information)")
    ap.add_argument("--against", type=Path, help="source tree of another version, run in the same pairs")
    args = ap.parse_args()
    other_env = None if args.against is None else {**ENV, "PYTHONPATH": str(args.against.resolve())}
    evo = shutil.which("evo_ape")
    if evo is None:
        raise SystemExit("evo_ape not found: pip install evo (a test-only extra of this project)")
    cli = [sys.executable, "-m", "cobot_analysis"]
    tmp = Path(tempfile.mkdtemp(prefix="bench-loc-"))
    load0 = os.getloadavg()
    started = datetime.now(timezone.utc)
    try:
        t_synth = run([*cli, "-q", "synth", "localisation", "--out", str(tmp), "--laps", str(args.laps),
                       "--speed", str(args.speed), "--formats", "ros1,mcap"])[0]
        truth = json.loads((tmp / "synth-localisation" / "truth.json").read_text())
        print(f"synthetic run: {truth['duration']:.0f} s, {truth['n_mocap']} mocap + {truth['n_icp']} ICP poses, "
              f"written (ROS1 + MCAP) in {t_synth:.1f} s", file=sys.stderr)
        rows, versus = [], []
        for name, sub in (("run.bag", "bag"), ("run.mcap", "mcap")):
            bag = str(tmp / "synth-localisation" / name)
            ours_cmd = [*cli, "-q", "localisation", bag, "--out", str(tmp / "ws"), "--no-figures", "--force"]
            evo_cmd = [evo, sub, bag, "/mocap/pose", "/icp/pose", "-a", "--sync_method", "interpolation",
                       "--t_offset", str(-truth["delay"]), "--no_warnings"]
            runs = {"ours": lambda: run(ours_cmd), "evo": lambda: run(evo_cmd)}
            if other_env is not None:
                runs["against"] = lambda: run(ours_cmd, other_env)
            times = {k: [] for k in runs}
            for f in runs.values():  # warm-up (bytecode and page caches), not counted
                f()
            order = list(runs)
            for k in range(args.pairs):
                for key in order[k % len(order):] + order[:k % len(order)]:  # each command first in turn
                    times[key].append(runs[key]())
                print(f"{name} pair {k + 1}: " + ", ".join(f"{key} {v[-1][0]:.2f} s" for key, v in times.items())
                      + f", ratio {times['ours'][-1][0] / times['evo'][-1][0]:.2f}", file=sys.stderr)
            ours, theirs = times["ours"], times["evo"]
            figs = run([*cli, "-q", "localisation", bag, "--out", str(tmp / "ws"), "--force"])[0] if args.figures else None
            ratio = statistics.median(o[0] / e[0] for o, e in zip(ours, theirs))
            cpu_ratio = statistics.median(o[1] / e[1] for o, e in zip(ours, theirs))
            med = lambda v, i: statistics.median(x[i] for x in v)  # noqa: E731
            mem_o, mem_e = max(x[2] for x in ours), max(x[2] for x in theirs)
            rows.append((name, ratio, cpu_ratio, med(ours, 0), med(theirs, 0), med(ours, 1), med(theirs, 1), mem_o, mem_e, figs))
            if other_env is not None:
                other = times["against"]
                rows.append((f"{name}, {args.against}", statistics.median(o[0] / e[0] for o, e in zip(other, theirs)),
                             statistics.median(o[1] / e[1] for o, e in zip(other, theirs)), med(other, 0), med(theirs, 0),
                             med(other, 1), med(theirs, 1), max(x[2] for x in other), mem_e, None))
                versus.append((name, statistics.median(o[0] / a[0] for o, a in zip(ours, other)),
                               statistics.median(o[1] / a[1] for o, a in zip(ours, other))))
        load1 = os.getloadavg()
        print(f"\n{started:%Y-%m-%d %H:%M} UTC, {platform.machine()}, {os.cpu_count()} cores, Python "
              f"{platform.python_version()}; load average (1, 5, 15 min) {load0[0]:.1f}, {load0[1]:.1f}, {load0[2]:.1f} "
              f"before and {load1[0]:.1f}, {load1[1]:.1f}, {load1[2]:.1f} after; {truth['duration']:.0f} s run; "
              f"{args.pairs} alternating pairs per bag after one warm-up run of each; whole processes (imports included).\n")
        print(f"ours: {' '.join(['cobot-analysis', *ours_cmd[3:]])}\nevo:  {' '.join(evo_cmd)}\n")
        print("| bag | wall ratio ours / evo (median of pairs) | CPU ratio (median of pairs) | ours wall (s) | evo wall (s) "
              "| ours CPU (s) | evo CPU (s) | ours peak RSS (MiB) | evo peak RSS (MiB) | memory ratio |"
              + (" ours with figures (s) |" if args.figures else ""))
        print("|---|---|---|---|---|---|---|---|---|---|" + ("---|" if args.figures else ""))
        for name, ratio, cpu_ratio, ow, ew, oc, ec, mo, me, f in rows:
            print(f"| {name} | **{ratio:.2f}** | {cpu_ratio:.2f} | {ow:.2f} | {ew:.2f} | {oc:.2f} | {ec:.2f} | {mo:.0f} | {me:.0f} | "
                  f"{mo / me:.2f} |" + (f" {f:.2f} |" if args.figures and f is not None else " |" if args.figures else ""))
        for name, wall, cpu in versus:
            print(f"\n{name}: this version / {args.against}: wall {wall:.3f}, CPU {cpu:.3f} (medians of the per-pair ratios)")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
