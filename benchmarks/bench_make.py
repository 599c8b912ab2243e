"""What each Makefile target costs (issue 22 point 5): a timing wrapper for `make ... CLI=...`, and its summary.

    make walking pairs CLI="python benchmarks/bench_make.py --log /tmp/make-times.jsonl --"
    python benchmarks/bench_make.py --summary /tmp/make-times.jsonl

As the wrapper, it runs the pipeline command it is given (``python -m cobot_analysis ARGS``, its exit code passed
on) and appends one JSON line to ``--log``: the command, its start (UTC), wall time, CPU time of the command and
its worker processes (user + system, from ``wait4``), peak resident memory of its largest process, and the load
average at the start and the end. Nothing else changes: the Makefile's commands, options and workspaces are the
same as with ``CLI=cobot-analysis``.

``--summary`` groups the lines by Makefile target, read from the command (the workspace ``--out`` names the study;
``--per subject`` is walking-subjects), and prints per stage and per target the wall and CPU time, against the
target of issue 22 (``make all`` under 20 min on this machine idle). The target is absolute: there is no reference
to alternate with, so the load is printed beside every figure and a loaded run is not an idle figure.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections import defaultdict
from datetime import datetime, timezone
from pathlib import Path

TARGET_MIN = 20.0
#: workspace directory name (Makefile: WALK, PAIRS, SPAIRS, LOC) -> make target
TARGETS = {"walking-2020": "walking", "pair-carriage-2022": "pairs-published", "synthetic-pairs": "pairs-synthetic",
           "localisation": "localisation"}


def target_of(args: list[str]) -> str:
    """The Makefile target a pipeline command belongs to, from its workspace (``--out``) and options."""
    out = next((args[i + 1] for i, a in enumerate(args[:-1]) if a == "--out"), "")
    if "--to" in args and args[0] == "results":
        return "results"
    name = TARGETS.get(Path(out).name, Path(out).name or args[0])
    if name == "walking" and "--per" in args:
        return "walking-subjects"
    return name


def stage_of(args: list[str]) -> str:
    """A short name of the command: the subcommand and the options that tell its Makefile lines apart."""
    words = [a for a in args if not a.startswith("-")]
    keep = ("--convention", "--method", "--model", "--stage-name", "--per", "--preprocess", "--entity")
    opts = [f"{a} {args[i + 1]}" if i + 1 < len(args) and not args[i + 1].startswith("-") else a
            for i, a in enumerate(args) if a in keep]
    head = words[:2] if words[:1] in (["synth"], ["import-published"]) else words[:1]
    return " ".join(head + opts) or " ".join(args)


def wrap(log: Path, args: list[str]) -> int:
    load0 = os.getloadavg()[0]
    started = datetime.now(timezone.utc)
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "cobot_analysis", *args])
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    code = os.waitstatus_to_exitcode(status)
    row = {"args": args, "target": target_of(args), "stage": stage_of(args), "start": f"{started:%Y-%m-%d %H:%M:%S}",
           "wall_s": round(wall, 2), "cpu_s": round(usage.ru_utime + usage.ru_stime, 2),
           "peak_mib": round(usage.ru_maxrss / 1024), "load_start": load0, "load_end": os.getloadavg()[0], "exit": code}
    with log.open("a") as f:
        f.write(json.dumps(row) + "\n")
    return code


def summary(log: Path) -> None:
    rows = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    if not rows:
        raise SystemExit(f"{log}: no timed command")
    by_target: dict[str, list[dict]] = defaultdict(list)
    for r in rows:
        by_target[r["target"]].append(r)
    print(f"{len(rows)} commands, {rows[0]['start']} to {rows[-1]['start']} UTC (start of the last); {os.cpu_count()} cores\n")
    print("| target | stage | wall (min) | CPU (min) | peak (MiB) | load start -> end | exit |")
    print("|---|---|---|---|---|---|---|")
    total_wall = total_cpu = 0.0
    for target, rs in by_target.items():
        for r in rs:
            print(f"| {target} | `{r['stage']}` | {r['wall_s'] / 60:.1f} | {r['cpu_s'] / 60:.1f} | {r['peak_mib']} | "
                  f"{r['load_start']:.1f} -> {r['load_end']:.1f} | {r['exit']} |")
        wall, cpu = sum(r["wall_s"] for r in rs), sum(r["cpu_s"] for r in rs)
        loads = [r["load_start"] for r in rs] + [r["load_end"] for r in rs]
        print(f"| **{target}** | all | **{wall / 60:.1f}** | {cpu / 60:.1f} | | {min(loads):.1f}-{max(loads):.1f} | |")
        total_wall, total_cpu = total_wall + wall, total_cpu + cpu
    loads = [r["load_start"] for r in rows] + [r["load_end"] for r in rows]
    print(f"\nall targets: **{total_wall / 60:.1f} min** wall (sum of the commands), {total_cpu / 60:.1f} min CPU; "
          f"load {min(loads):.1f}-{max(loads):.1f}; target make all < {TARGET_MIN:.0f} min idle: "
          f"{'met' if total_wall / 60 < TARGET_MIN else 'not met'}"
          f"{'' if max(loads) <= 1.5 else ' (a loaded run: not an idle figure; CPU / 2 cores = ' + f'{total_cpu / 120:.1f} min)'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--log", type=Path, help="append one JSON line per command to this file (wrapper mode)")
    ap.add_argument("--summary", type=Path, metavar="LOG", help="print the per-target table of a log")
    ap.add_argument("args", nargs=argparse.REMAINDER, help="-- then the pipeline command's arguments")
    a = ap.parse_args()
    if a.summary:
        summary(a.summary)
        return
    args = a.args[1:] if a.args[:1] == ["--"] else a.args
    if a.log is None or not args:
        ap.error("wrapper mode needs --log LOG -- ARGS (or --summary LOG)")
    sys.exit(wrap(a.log, args))


if __name__ == "__main__":
    main()
