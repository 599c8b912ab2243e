"""The test suite a contributor runs, and CI, against the targets of issue 22 point 4.

    python benchmarks/bench_suite.py [--checkout DIR] [--ci] [--serial] [--pytest-args "-x -q"]

Runs README command 2 (``python -m pytest``, the quick selection) in the checkout (default: this one, with it
first on ``PYTHONPATH``), and with ``--ci`` then ``./.ci/run`` (the quick and the slow selections and the metric
regression; set ``COBOT_DATASETS`` / ``COBOT_REALDATA`` as for CI). Prints for each the wall time, the CPU time of
the command and everything it ran (user + system), the pytest summary line, the exit code and the load average
before and after, against the targets: README command 2 under 2.5 min and ``.ci/run`` under 6 min, on this machine
idle. The targets are absolute, so there is no reference to alternate with: a run at a load above about 1.5 is
reported as loaded, and its CPU time / cores is printed as the bound an idle machine would give if the run kept
both cores busy. ``--pytest-args`` replaces pytest's arguments (e.g. ``-k startup`` to try the script on a few
tests); the targets then do not apply. ``--serial`` runs README command 2 a second time with ``-n 0`` (the tests in
one process, as before pytest-xdist) and prints the ratio of the two wall and CPU times, measured in the same run.
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGETS = {"README command 2": 150.0, ".ci/run": 360.0}


def timed(name: str, cmd: list[str], cwd: Path, env: dict[str, str]) -> dict:
    load0 = os.getloadavg()[0]
    started = datetime.now(timezone.utc)
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    for line in proc.stdout:
        lines.append(line)
        sys.stderr.write(line)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    summary = [ln.strip("= \n") for ln in lines if re.search(r"\d+ (passed|failed|error)", ln)]
    return {"name": name, "cmd": " ".join(cmd), "start": f"{started:%Y-%m-%d %H:%M}", "wall": wall,
            "cpu": usage.ru_utime + usage.ru_stime, "exit": os.waitstatus_to_exitcode(status),
            "summary": "; ".join(summary[-3:]) or "(no pytest summary line)", "load0": load0, "load1": os.getloadavg()[0]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkout", type=Path, default=ROOT, help="the checkout to test (default: this one)")
    ap.add_argument("--ci", action="store_true", help="also run ./.ci/run (several minutes; the whole of CI)")
    ap.add_argument("--pytest-args", help="pytest's arguments instead of none (README command 2); no target then")
    ap.add_argument("--serial", action="store_true", help="also README command 2 with -n 0 (one process): the ratio")
    a = ap.parse_args()
    checkout = a.checkout.resolve()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(checkout), os.environ.get("PYTHONPATH")]))}
    extra = shlex.split(a.pytest_args) if a.pytest_args else []
    runs = [timed("README command 2", [sys.executable, "-m", "pytest", *extra], checkout, env)]
    if a.serial:
        runs.append(timed("README command 2, -n 0", [sys.executable, "-m", "pytest", *extra, "-n", "0"], checkout, env))
    if a.ci:
        runs.append(timed(".ci/run", ["./.ci/run"], checkout, env))
    cores = os.cpu_count() or 1
    print(f"\n{checkout} ({subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=checkout, capture_output=True, text=True).stdout.strip()}), "
          f"{cores} cores\n")
    print("| command | start (UTC) | wall (s) | CPU (s) | CPU / cores (s) | load start -> end | exit | pytest | target |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in runs:
        target = TARGETS.get(r["name"]) if not extra else None
        loaded = max(r["load0"], r["load1"]) > 1.5
        verdict = ("-" if target is None else f"< {target:.0f} s: {'met' if r['wall'] < target else 'not met'}"
                   + (" (loaded: not an idle figure)" if loaded else ""))
        print(f"| `{r['cmd']}` | {r['start']} | **{r['wall']:.1f}** | {r['cpu']:.1f} | {r['cpu'] / cores:.1f} | "
              f"{r['load0']:.1f} -> {r['load1']:.1f} | {r['exit']} | {r['summary']} | {verdict} |")
    if a.serial:
        quick, serial = runs[0], runs[1]
        print(f"\nREADME command 2 / the same with -n 0: wall {quick['wall'] / serial['wall']:.2f}, "
              f"CPU {quick['cpu'] / serial['cpu']:.2f}")
    sys.exit(max(r["exit"] for r in runs))


if __name__ == "__main__":
    main()
